"""Behaviour cloning from a demonstration dataset, then reinforcement learning (``polyenvs train --bc-from DIR``).

The `imitation` package would be the well-kept choice, but it pins gymnasium 0.29 and Stable-Baselines3 2.2
(checked with ``pip install --dry-run imitation``: it would downgrade both), so this is a small supervised loop over
the SB3 policy itself, before PPO starts (kickstarting, as in DAPG without the demonstration term):

1. the VecNormalize statistics, where the config normalises, are set from the demonstrations: observations from
   their mean and variance, rewards from the discounted running returns VecNormalize itself would have tracked;
2. the policy maximises the log-likelihood of the demonstrated actions (``policy.evaluate_actions``: a Gaussian for
   Box actions, whose log_std falls as the fit tightens; categorical for Discrete and MultiDiscrete), and the value
   head regresses the demonstrations' discounted returns (in the normalised reward scale), so that PPO's first
   advantages are not measured against an untrained critic;
3. PPO trains from there with the config's hyperparameters.

The dataset (a directory ``polyenvs collect`` wrote) must be of the training id, with the same observation and
action spaces; the algorithm must be an actor-critic one (ppo, maskable_ppo). run.json records the dataset and
these settings under ``"bc"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from polyenvs.errors import InputError, check_count
from polyenvs.limits import MAX_BC_EPOCHS
from polyenvs.registry import bare_id

if TYPE_CHECKING:  # the datasets need gymnasium and minari: imported when a dataset is read
    from polyenvs.evaluation.datasets import Demonstrations

__all__ = ["BC_ALGOS", "DEFAULT_BC_EPOCHS", "BehaviourCloning"]

#: Algorithms whose policy has an actor and a critic to pretrain (``evaluate_actions``).
BC_ALGOS = ("ppo", "maskable_ppo")
#: Passes over the demonstrations (learning.md's corridor study: 15 epochs of 200 demonstrations).
DEFAULT_BC_EPOCHS = 10


@dataclass
class BehaviourCloning:
    """Pretraining a new model on the demonstrations in ``dataset`` before it learns (see the module docstring).

    Args:
        dataset: the directory ``polyenvs collect`` wrote.
        epochs: passes over the demonstrations.
        batch_size: demonstration steps per gradient step.
        learning_rate: Adam's step size (its own optimiser: PPO's starts fresh afterwards).
        value_coef: the weight of the value head's squared error beside the actions' negative log-likelihood.
        log_std: for Box actions, set the Gaussian's log standard deviation to this after the fit (PPO's
            exploration from the cloned policy; the issue's study used -1.7 on AP-lite, -4 on the beast, whose gait
            breaks under noise); ``None`` keeps what the fit learned.
        flag: how errors name the dataset (``--bc-from`` on the command line).
    """

    dataset: Path
    epochs: int = DEFAULT_BC_EPOCHS
    batch_size: int = 256
    learning_rate: float = 1e-3
    value_coef: float = 0.5
    log_std: float | None = None
    flag: str = "bc_from"
    _demonstrations: Demonstrations | None = field(default=None, repr=False)

    def __post_init__(self):
        self.dataset = Path(self.dataset)
        self.epochs = check_count("bc_epochs", self.epochs, 1, MAX_BC_EPOCHS)
        self.batch_size = check_count("bc batch_size", self.batch_size, 1)

    def demonstrations(self) -> Demonstrations:
        """The dataset's episodes (read once); an :class:`InputError` naming :attr:`flag` if it cannot be."""
        from polyenvs.evaluation.datasets import load_demonstrations

        if self._demonstrations is None:
            try:
                self._demonstrations = load_demonstrations(self.dataset)
            except InputError as exc:
                raise InputError(f"{self.flag} {exc}") from None
        return self._demonstrations

    def check(self, algo: str, target, frame_stack: int | None = None) -> dict[str, Any]:
        """The run.json record of the pretraining, once the dataset fits ``algo`` and the training environment
        ``target`` (:class:`polyenvs.evaluation.episodes.EnvTarget`); else an :class:`InputError`, before any training."""
        from gymnasium import spaces

        from baselines.trained import _same_space

        if algo not in BC_ALGOS:
            raise InputError(f"{self.flag} pretrains an actor-critic policy: --algo must be one of {BC_ALGOS}")
        if self.log_std is not None and not isinstance(target.action_space, spaces.Box):
            raise InputError(f"{self.flag}: a log_std is for Box actions; {target.env_id} has {target.action_space}")
        if frame_stack is not None:
            raise InputError(f"{self.flag}: the config stacks frames, and the demonstrations are single frames")
        demos = self.demonstrations()
        where = f"{self.flag} {self.dataset}"
        if bare_id(demos.info["env_id"]) != target.env_id:
            raise InputError(f"{where}: demonstrations of {demos.info['env_id']}, not of {target.env_id}")
        for name, theirs, ours in (("observation", demos.observation_space, target.observation_space),
                                   ("action", demos.action_space, target.action_space)):  # fmt: skip
            if not _same_space(theirs, ours):
                raise InputError(f"{where}: its {name} space is {theirs}, the environment's is {ours}")
        info = demos.info
        theirs, ours = (
            (kwargs or {}).get("layouts", "default") for kwargs in (info.get("env_kwargs"), target.env_kwargs)
        )
        if theirs != ours:  # the Procgen protocol: a run learns from its own training layouts, demonstrations too
            raise InputError(
                f"{where}: demonstrations on the {theirs!r} layouts, the run trains on {ours!r}: collect them with "
                f'--env-kwargs \'{{"layouts": "{ours}"}}\' (or train with --layouts {theirs})'
            )
        return {
            "dataset": {
                key: info.get(key)
                for key in ("path", "dataset_id", "env_id", "env_kwargs", "policy", "policy_name", "seeds", "episodes")
            },  # fmt: skip
            "steps": demos.steps,
            "epochs": self.epochs,
            "batch_size": self.batch_size,
            "learning_rate": self.learning_rate,
            "value_coef": self.value_coef,
            "log_std": self.log_std,
        }

    def pretrain(self, model) -> dict[str, Any]:
        """Set ``model``'s normalisation statistics and fit its policy to the demonstrations; the fit's numbers."""
        import torch

        demos = self.demonstrations()
        observations = np.concatenate([obs[:-1] for obs, _, _ in demos.episodes])
        normalizer = model.get_vec_normalize_env()
        if normalizer is not None:
            _set_statistics(normalizer, demos)
            observations = normalizer.normalize_obs(observations)
        returns = np.concatenate([_discounted(rewards, model.gamma) for _, _, rewards in demos.episodes])
        if normalizer is not None and normalizer.norm_reward:
            returns = returns / np.sqrt(normalizer.ret_rms.var + normalizer.epsilon)
        policy = model.policy
        tensors = (
            torch.as_tensor(observations, dtype=torch.float32, device=policy.device),
            _action_tensor(np.concatenate([actions for _, actions, _ in demos.episodes]), model.action_space,
                           policy.device),
            torch.as_tensor(returns, dtype=torch.float32, device=policy.device),
        )  # fmt: skip
        self._fit(policy, tensors, seed=model.seed or 0)
        quality = _fit_quality(policy, model.action_space, tensors)  # of the fit itself, before log_std is set
        if self.log_std is not None:
            with torch.no_grad():
                policy.log_std.fill_(self.log_std)
        return {"fit": quality}

    def _fit(self, policy, tensors, seed: int) -> None:
        import torch

        observations, actions, returns = tensors
        optimizer = torch.optim.Adam(policy.parameters(), lr=self.learning_rate)
        generator = torch.Generator().manual_seed(int(seed))  # the batches' order: the same run, the same fit
        policy.set_training_mode(True)
        for _ in range(self.epochs):
            order = torch.randperm(len(observations), generator=generator)
            for start in range(0, len(order), self.batch_size):
                batch = order[start : start + self.batch_size]
                values, log_prob, _ = policy.evaluate_actions(observations[batch], actions[batch])
                value_loss = torch.nn.functional.mse_loss(values.flatten(), returns[batch])
                loss = -log_prob.mean() + self.value_coef * value_loss
                optimizer.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
                optimizer.step()
        policy.set_training_mode(False)


def _discounted(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """Each step's discounted return to the episode's end."""
    out = np.empty(len(rewards))
    total = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        total = rewards[t] + gamma * total
        out[t] = total
    return out


def _set_statistics(normalizer, demos: Demonstrations) -> None:
    """VecNormalize's running statistics as if it had watched the demonstrations (it keeps updating in training)."""
    if normalizer.norm_obs:
        normalizer.obs_rms.update(np.concatenate([obs for obs, _, _ in demos.episodes]))
    if normalizer.norm_reward:  # VecNormalize scales rewards by the spread of the running discounted return
        running = []
        for _, _, rewards in demos.episodes:
            total = 0.0
            for reward in rewards:
                total = total * normalizer.gamma + reward
                running.append(total)
        normalizer.ret_rms.update(np.asarray(running))


def _action_tensor(actions: np.ndarray, action_space, device):
    """The demonstrated actions as ``evaluate_actions`` takes them (as PPO's own update passes them)."""
    import torch
    from gymnasium import spaces

    if isinstance(action_space, spaces.Discrete):
        return torch.as_tensor(actions.reshape(-1), dtype=torch.long, device=device)
    if isinstance(action_space, spaces.MultiDiscrete | spaces.MultiBinary):
        return torch.as_tensor(actions.reshape(len(actions), -1), dtype=torch.long, device=device)
    return torch.as_tensor(actions.reshape(len(actions), -1), dtype=torch.float32, device=device)


def _fit_quality(policy, action_space, tensors) -> dict[str, float]:
    """How closely the pretrained policy follows the demonstrations: their mean negative log-likelihood, and the
    fraction of steps whose deterministic action is the demonstrated one (discrete) or its mean absolute error."""
    import torch
    from gymnasium import spaces

    observations, actions, _ = tensors
    with torch.no_grad():
        _, log_prob, _ = policy.evaluate_actions(observations, actions)
        chosen = policy._predict(observations, deterministic=True)
    quality = {"nll": float(-log_prob.mean())}
    if isinstance(action_space, spaces.Box):
        quality["action_mae"] = float((chosen.reshape(actions.shape) - actions).abs().mean())
    else:
        quality["action_agreement"] = float((chosen.reshape(actions.shape) == actions).float().mean())
    return quality
