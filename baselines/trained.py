"""Trained Stable-Baselines3 models as policies, with the same ``predict`` interface as the hand baselines.

A trained model is named by a path: a training directory or a ``.zip``. A training directory (what
``polyenvs train`` writes) holds

- ``model.zip``: the model, ``model.save(...)`` of Stable-Baselines3 or sb3-contrib;
- ``vecnormalize.pkl`` (optional): the ``VecNormalize`` statistics the model was trained with;
- ``run.json``: ``{"env_id", "algo", "seed", "timesteps", "requested_timesteps", "n_envs", "env_kwargs",
  "hyperparams", "command", "versions", "git_commit", "wall_clock_s", "completed"}``, and ``"residual"``
  (``{"baseline", "scale", "observe_base", "hold"}``) for a residual agent.

A residual agent (``polyenvs train --residual``, :mod:`baselines.residual`) learned a correction of a hand baseline:
its model sees the observation with the base action appended and outputs the correction. Loaded, it rebuilds the
baseline from run.json and composes the two inside :meth:`TrainedPolicy.predict`, its ``state`` the baseline's
memory, so it acts on the environment as registered, wherever a model does. A model trained on stacked observations
(the config's ``frame_stack``, SB3's ``VecFrameStack``) likewise stacks them itself, in its ``state``.

For a bare ``.zip``, a ``run.json`` beside it is used when there is one, and the normalisation statistics are looked
for beside it (``vecnormalize.pkl``) and where RL Zoo keeps them (``<name>/vecnormalize.pkl`` for ``<name>.zip``);
without a ``run.json`` the algorithm is read from the saved policy class and confirmed by loading.

:class:`TrainedPolicy` applies the saved observation normalisation (``VecNormalize.normalize_obs``; rewards are not
normalised, the statistics are never updated) and passes the action mask to a ``MaskablePPO`` model when the caller
supplies one (``predict(..., action_masks=...)``; the evaluation loop passes ``info["action_mask"]``).

Everything that can be wrong with a model (a missing path, a corrupt zip, a ``run.json`` for another environment,
observation or action spaces that do not match) raises :class:`TrainedModelError` (a ``ValueError``) with one line,
when the policy is built: before any episode runs. Stable-Baselines3 is imported only when a model is loaded.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from baselines.algorithms import ALGOS
from baselines.residual.compose import ResidualComposer, ResidualSpec, make_composer
from polyenvs.core.extras import install_hint
from polyenvs.pool import single_threaded_torch
from polyenvs.registry import bare_id

__all__ = [
    "LeanActor",
    "TrainedModelError",
    "TrainedPolicy",
    "is_model_path",
    "load_trained_policy",
    "model_checksum",
    "read_run_info",
    "resolve_model_files",
]

#: The module of a saved policy class -> the algorithm to try first when no run.json says which.
_POLICY_MODULES = {
    "sb3_contrib.common.maskable.policies": "maskable_ppo",
    "stable_baselines3.common.policies": "ppo",
    "stable_baselines3.dqn.policies": "dqn",
    "stable_baselines3.sac.policies": "sac",
    "stable_baselines3.td3.policies": "td3",
}
#: Schedules are pickled closures that need not load in another Python or package version; inference never uses
#: them (the same replacements as RL Zoo's ``enjoy``).
_CUSTOM_OBJECTS = {
    "learning_rate": 0.0,
    "lr_schedule": lambda _: 0.0,
    "clip_range": lambda _: 0.0,
    "exploration_schedule": lambda _: 0.0,
}
MODEL_FILE, NORMALIZE_FILE, RUN_FILE = "model.zip", "vecnormalize.pkl", "run.json"


class TrainedModelError(ValueError):
    """A trained model that cannot be used here; the message is one line naming the path."""


def is_model_path(name: str) -> bool:
    """Whether a ``--policy`` value names a file or directory rather than a baseline: it exists, ends in ``.zip``,
    or contains a path separator."""
    name = os.fspath(name)
    return name.endswith(".zip") or os.sep in name or "/" in name or Path(name).exists()


def resolve_model_files(path: str | os.PathLike) -> tuple[Path, Path | None, Path | None]:
    """``(model.zip, vecnormalize.pkl or None, run.json or None)`` for a training directory or a ``.zip``."""
    path = Path(path)
    if path.is_dir():
        model = path / MODEL_FILE
        if not model.is_file():
            raise TrainedModelError(f"{path}: a training directory must hold {MODEL_FILE}, and this one does not")
        normalize = path / NORMALIZE_FILE
        run = path / RUN_FILE
        return model, (normalize if normalize.is_file() else None), (run if run.is_file() else None)
    if not path.exists():
        raise TrainedModelError(f"{path}: no such training directory or model file")
    if not path.is_file():
        raise TrainedModelError(f"{path}: not a training directory or a model file")
    candidates = [path.parent / NORMALIZE_FILE, path.with_suffix("") / NORMALIZE_FILE]  # beside it; RL Zoo's place
    normalize = next((p for p in candidates if p.is_file()), None)
    run = path.parent / RUN_FILE
    return path, normalize, (run if run.is_file() else None)


def read_run_info(run_file: Path | None) -> dict[str, Any]:
    """The run.json document (``{}`` without one); a file that is not a JSON object raises."""
    if run_file is None:
        return {}
    try:
        info = json.loads(Path(run_file).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise TrainedModelError(f"{run_file}: cannot be read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise TrainedModelError(f"{run_file}: not valid JSON ({exc})") from None
    if not isinstance(info, dict):
        raise TrainedModelError(f"{run_file}: must be a JSON object")
    algo = info.get("algo")
    if algo is not None and algo not in ALGOS:
        raise TrainedModelError(f"{run_file}: unknown algo {algo!r}; known: {', '.join(ALGOS)}")
    return info


def model_checksum(model_file: Path, normalize_file: Path | None = None) -> str:
    """SHA-256 of the model and its normalisation statistics: a result names the exact model it evaluated."""
    digest = hashlib.sha256()
    for file in (model_file, normalize_file):
        if file is not None:
            digest.update(Path(file).read_bytes())
    return digest.hexdigest()


def _bare_id(env_id: str | None) -> str | None:
    return None if env_id is None else bare_id(str(env_id))


def _space_text(space: spaces.Space) -> str:
    if isinstance(space, spaces.Box):
        return f"Box{space.shape}"
    return str(space)


def _same_space(a: spaces.Space, b: spaces.Space) -> bool:
    """Same kind and size (bounds may differ with environment keywords; SB3 clips or rescales to its own)."""
    if type(a) is not type(b) or a.shape != b.shape:
        return False
    if isinstance(a, spaces.Discrete):
        return a.n == b.n and a.start == b.start
    if isinstance(a, spaces.MultiDiscrete):
        return np.array_equal(a.nvec, b.nvec)
    if isinstance(a, spaces.Dict):
        return a.keys() == b.keys() and all(_same_space(a[k], b[k]) for k in a.keys())
    return True


def _algorithm_class(algo: str):
    module_name, class_name = ALGOS[algo].module, ALGOS[algo].class_name
    try:
        module = __import__(module_name, fromlist=[class_name])
    except ImportError:
        package = {"stable_baselines3": "Stable-Baselines3", "sb3_contrib": "sb3-contrib"}[module_name]
        raise TrainedModelError(f"a trained {algo} model needs {package}: {install_hint('train')}") from None
    return getattr(module, class_name)


def _saved_policy_algo(model_file: Path) -> str | None:
    """The algorithm a saved zip's policy class belongs to, read from its ``data`` entry (no unpickling)."""
    try:
        with zipfile.ZipFile(model_file) as archive:
            data = json.loads(archive.read("data"))
        return _POLICY_MODULES.get(data["policy_class"]["__module__"])
    except (KeyError, TypeError, ValueError, OSError, zipfile.BadZipFile):
        return None


def _check_archive(model_file: Path) -> None:
    try:
        with zipfile.ZipFile(model_file) as archive:
            names = archive.namelist()
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise TrainedModelError(
            f"{model_file}: not a Stable-Baselines3 model (not a readable zip file: {exc})"
        ) from None
    if "data" not in names or "policy.pth" not in names:
        raise TrainedModelError(f"{model_file}: not a Stable-Baselines3 model (no data or policy.pth inside)")
    if bad is not None:
        raise TrainedModelError(f"{model_file}: corrupt zip file ({bad} fails its CRC check)")


def _load_model(model_file: Path, algo: str | None):
    """``(model, algo)``: with ``algo`` that class only; without, the saved policy's algorithm first, then the rest."""
    _check_archive(model_file)
    # One torch thread, whatever the machine: with more, batched inference sums in another order, an action's last
    # bits change and a chaotic episode diverges (the formation's PPO agents did, 1 against 2 threads); so a result
    # would depend on the core count.
    single_threaded_torch()
    if algo is not None:
        order = [algo]
    else:
        hint = _saved_policy_algo(model_file)
        order = ([hint] if hint else []) + [a for a in ALGOS if a != hint]
    failures = []
    for name in order:
        try:
            cls = _algorithm_class(name)
        except TrainedModelError as exc:
            failures.append(str(exc))
            continue
        try:
            return cls.load(model_file, device="cpu", custom_objects=_CUSTOM_OBJECTS), name
        except Exception as exc:  # noqa: BLE001 - any failure to unpickle or build the model is a bad file here
            failures.append(f"as {name}: {type(exc).__name__}: {exc}".replace("\n", " "))
    if algo is not None:
        raise TrainedModelError(f"{model_file}: cannot load it as {algo} ({failures[0]})")
    raise TrainedModelError(f"{model_file}: cannot load it as any of {', '.join(order)} ({failures[0]})")


def _load_normalization(normalize_file: Path, observation_space: spaces.Space):
    try:
        with open(normalize_file, "rb") as fh:
            stats = pickle.load(fh)
    except Exception as exc:  # noqa: BLE001 - unpickling can raise anything for a corrupt file
        raise TrainedModelError(f"{normalize_file}: cannot load it ({type(exc).__name__}: {exc})") from None
    if not hasattr(stats, "normalize_obs") or not hasattr(stats, "obs_rms"):
        raise TrainedModelError(f"{normalize_file}: does not hold VecNormalize statistics")
    stats.training = False  # never update the statistics while evaluating
    stats.norm_reward = False
    if stats.norm_obs and not isinstance(observation_space, spaces.Dict):
        shape = np.shape(getattr(stats.obs_rms, "mean", None))
        if shape != observation_space.shape:
            raise TrainedModelError(
                f"{normalize_file}: statistics for observations of shape {shape}, "
                f"but the environment gives {_space_text(observation_space)}"
            )
    return stats


def _normalize_requested(run: dict) -> bool:
    """Whether run.json says observations were normalised: ``normalize`` true, a non-empty string (RL Zoo's
    ``"dict(...)"``), or VecNormalize's arguments without ``norm_obs: false``."""
    hyperparams = run.get("hyperparams")
    value = hyperparams.get("normalize", False) if isinstance(hyperparams, dict) else False
    if isinstance(value, dict):
        return value.get("norm_obs", True) is not False
    if isinstance(value, str):
        return (
            value.strip().lower() not in ("", "false", "0", "none")
            and "norm_obs=false" not in value.replace(" ", "").lower()
        )
    return bool(value)


class LeanActor:
    """Stable-Baselines3's deterministic ``predict`` for an MLP actor-critic policy (PPO's and A2C's
    ``ActorCriticPolicy`` with a Gaussian, gSDE included, or a categorical action; MaskablePPO's with its action
    masks; flat Box observations), with the saved observation normalisation, in the same torch and numpy operations
    on the same dtypes and batch shapes, so the same actions bit for bit (``tests/test_lean_actor.py``), without
    SB3's per-call work around them (the training-mode switch over every module, a distribution object with its
    argument checks): on a beast PPO agent that was about two thirds of a step (1.72 -> 0.61-0.65 ms a step,
    measured on a loaded machine). :meth:`for_model` returns None for any other policy, which keeps SB3's predict.
    """

    def __init__(self, policy, normalization=None):
        import torch

        policy.set_training_mode(False)  # what SB3's predict does at every call; these MLPs have no dropout or norm
        self.policy = policy
        self.torch = torch
        self.shape = policy.observation_space.shape
        self.action_shape = policy.action_space.shape
        self.box = isinstance(policy.action_space, spaces.Box)
        self.n_actions = None if self.box else int(policy.action_space.n)
        self.normalization = None
        if normalization is not None and normalization.norm_obs:
            rms = normalization.obs_rms
            # VecNormalize._normalize_obs computes this divisor afresh at every call, always to the same bits.
            self.normalization = (rms.mean, np.sqrt(rms.var + normalization.epsilon), normalization.clip_obs)

    @classmethod
    def for_model(cls, model, normalization=None) -> LeanActor | None:
        """The lean actor of ``model``, or None where its ``predict`` does more than this class repeats."""
        from stable_baselines3.common import distributions as dist
        from stable_baselines3.common.policies import ActorCriticPolicy

        kinds = {ActorCriticPolicy: (dist.DiagGaussianDistribution, dist.StateDependentNoiseDistribution,
                                     dist.CategoricalDistribution)}  # fmt: skip
        try:
            from sb3_contrib.common.maskable.distributions import MaskableCategoricalDistribution
            from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy

            kinds[MaskableActorCriticPolicy] = (MaskableCategoricalDistribution,)
        except ImportError:  # sb3-contrib is optional
            pass
        policy = getattr(model, "policy", None)
        if type(policy) not in kinds or policy.squash_output:
            return None  # SAC's, TD3's, DQN's, recurrent and CNN policies keep SB3's predict
        flat = isinstance(policy.observation_space, spaces.Box) and len(policy.observation_space.shape) == 1
        # The mode of each: the mean (gSDE's too, without its tanh bijector), or the most probable category.
        known = kinds[type(policy)]
        if not flat or type(policy.action_dist) not in known or getattr(policy.action_dist, "bijector", None):
            return None
        if normalization is not None and isinstance(normalization.obs_rms, dict):
            return None
        return cls(policy, normalization)

    def __call__(self, observation, action_masks=None) -> np.ndarray:
        """The deterministic action for one observation, or one per row of a batch; ``action_masks`` (bool, one row
        per observation) as MaskablePPO's predict takes them."""
        torch = self.torch
        obs = np.asarray(observation)
        single = obs.shape == self.shape
        if not single and obs.shape[1:] != self.shape:
            raise ValueError(f"observation of shape {obs.shape}: expected {self.shape} or a batch of them")
        if self.normalization is not None:  # VecNormalize.normalize_obs
            mean, std, clip = self.normalization
            obs = np.clip((obs - mean) / std, -clip, clip).astype(np.float32)
        policy = self.policy
        with torch.no_grad():  # ActorCriticPolicy.obs_to_tensor, preprocess_obs, get_distribution, then the mode
            tensor = torch.as_tensor(obs.reshape((-1, *self.shape))).float()
            head = policy.action_net(policy.mlp_extractor.forward_actor(policy.pi_features_extractor(tensor)))
            if not self.box:
                head = self._mode(head, action_masks)
        actions = head.numpy().reshape((-1, *self.action_shape))
        if self.box:
            actions = np.clip(actions, policy.action_space.low, policy.action_space.high)
        return actions.squeeze(axis=0) if single else actions

    def _mode(self, logits, action_masks):
        """The most probable category as torch's ``Categorical(logits).probs.argmax`` takes it, with the mask
        applied as sb3-contrib's ``MaskableCategorical.apply_masking`` does (masked logits -1e8, normalised again)."""
        torch = self.torch
        logits = logits.view(-1, self.n_actions)
        logits = logits - logits.logsumexp(dim=-1, keepdim=True)
        if action_masks is not None:
            masks = torch.as_tensor(action_masks, dtype=torch.bool).reshape(logits.shape)
            logits = torch.where(masks, logits, torch.tensor(-1e8, dtype=logits.dtype))
            logits = logits - logits.logsumexp(dim=-1, keepdim=True)
        return torch.argmax(torch.nn.functional.softmax(logits, dim=-1), dim=1)


class TrainedPolicy:
    """A loaded Stable-Baselines3 model behind the hand baselines' ``predict`` interface.

    Use :func:`load_trained_policy` to build one; it checks the model against the environment.
    """

    def __init__(
        self, model, algo: str, path: str, *, normalization=None, run: dict | None = None, checksum=None,
        residual: ResidualComposer | None = None, stack: ObservationStack | None = None,
    ):  # fmt: skip
        self.model = model
        self.algo = algo
        self.path = str(path)
        self.normalization = normalization
        self.run = dict(run or {})
        self.checksum = checksum
        #: The baseline a residual agent corrects (None for a plain model).
        self.residual = residual
        #: The frames a model trained with ``frame_stack`` sees (None: one observation).
        self.stack = stack
        # What the environment gives: the model's own space, unless a residual or a stack stands between them.
        self.observation_space = (
            residual.env_observation_space if residual is not None
            else stack.observation_space if stack is not None
            else model.observation_space
        )  # fmt: skip
        self.action_space = model.action_space if residual is None else residual.env_action_space
        self.uses_action_masks = algo == "maskable_ppo"
        #: SB3's deterministic predict without its per-call overhead, where the policy allows it (else None).
        self.lean = LeanActor.for_model(model, normalization)

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True, action_masks=None):
        """``(action, state)`` for one observation or a batch, as SB3's ``predict``; ``action_masks`` (a bool or
        0/1 array, one row per environment) reaches MaskablePPO models and is ignored by the others. A residual
        agent's ``state`` is its baseline's memory, its held correction and its tick count
        (:meth:`~baselines.residual.ResidualComposer.act`): called every control tick, it asks its network every
        ``hold`` ticks, as the wrapper it trained in did. A model trained on stacked frames (``frame_stack``) keeps
        its stack in ``state`` (:class:`ObservationStack`)."""
        if self.residual is not None:
            correct = functools.partial(self._correction, deterministic=deterministic)
            return self.residual.act(observation, state, episode_start, correct)
        if self.stack is not None:
            stacked, state = self.stack.push(observation, state, episode_start)
            return self._model_predict(stacked, None, None, deterministic, action_masks)[0], state
        return self._model_predict(observation, state, episode_start, deterministic, action_masks)

    def _correction(self, agent_observations, deterministic: bool) -> np.ndarray:
        """A residual agent's network: its corrections for a batch of what the residual wrapper shows it."""
        return self._model_predict(agent_observations, None, None, deterministic, None)[0]

    def _model_predict(self, observation, state, episode_start, deterministic, action_masks):
        kwargs = {}
        if self.uses_action_masks and action_masks is not None:
            kwargs["action_masks"] = np.asarray(action_masks).astype(bool)
        if deterministic and self.lean is not None:
            return self.lean(observation, **kwargs), state
        obs = observation
        if self.normalization is not None:
            obs = self.normalization.normalize_obs(np.asarray(observation))
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic, **kwargs)

    def describe(self) -> dict:
        """Algorithm, training seed, timesteps and the path (stored with evaluation results)."""
        timesteps = self.run.get("timesteps", getattr(self.model, "num_timesteps", None))
        description = {
            "name": self.algo,
            "algo": self.algo,
            "path": self.path,
            "training_seed": self.run.get("seed", getattr(self.model, "seed", None)),
            "timesteps": timesteps,
            "normalize": self.normalization is not None,
        }
        if self.uses_action_masks:
            description["action_masks"] = True
        if self.residual is not None:
            description["residual"] = self.residual.describe()
        if self.stack is not None:
            description["frame_stack"] = self.stack.frames
        if self.run.get("completed") is False:
            description["completed"] = False
            description["requested_timesteps"] = self.run.get("requested_timesteps")
        if self.checksum is not None:
            description["sha256"] = self.checksum
        return description


class ObservationStack:
    """The observation stack of SB3's ``VecFrameStack`` (a config's ``frame_stack``) for a model acting on the
    environment as registered: each row's last ``frames`` observations side by side, oldest first, zeros before its
    episode's first, carried as ``predict``'s ``state`` (so the evaluation loop keeps it per row and per robot)."""

    def __init__(self, frames: int, observation_space: spaces.Box):
        self.frames = frames
        self.observation_space = observation_space
        self.width = observation_space.shape[-1]
        self.dtype = observation_space.dtype
        # VecFrameStack's space (its bounds repeated, not tiled: the model saved that one)
        self.stacked_space = spaces.Box(
            np.repeat(observation_space.low, frames, axis=-1),
            np.repeat(observation_space.high, frames, axis=-1),
            dtype=observation_space.dtype,
        )

    def push(self, observation, state, episode_start) -> tuple[np.ndarray, np.ndarray]:
        """``(stacked observation, new state)``: ``observation`` (one or a batch) appended to each row's stack, a
        row whose episode starts (or with no state yet) emptied first."""
        rows = np.asarray(observation, dtype=self.dtype).reshape(-1, self.width)
        if state is None:
            stack = np.zeros((rows.shape[0], self.frames * self.width), dtype=self.dtype)
        else:
            stack = np.roll(np.asarray(state, dtype=self.dtype).reshape(rows.shape[0], -1), -self.width, axis=-1)
            if episode_start is not None:
                stack[np.broadcast_to(np.asarray(episode_start, dtype=bool), rows.shape[:1])] = 0
        stack[:, -self.width :] = rows
        single = np.ndim(observation) == 1
        return (stack[0] if single else stack), stack


def _stack_of(path, run: dict, run_file, observation_space) -> ObservationStack | None:
    """The observation stack of a run.json whose config stacked frames (None without one)."""
    hyperparams = run.get("hyperparams") if isinstance(run.get("hyperparams"), dict) else {}
    frames = hyperparams.get("frame_stack")
    if frames is None:
        return None
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise TrainedModelError(f"{path}: {run_file}: frame_stack must be a positive integer, got {frames!r}")
    if "residual" in run:
        raise TrainedModelError(f"{path}: {run_file}: a residual agent with stacked frames is not supported")
    if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
        raise TrainedModelError(f"{path}: frame_stack stacks flat Box observations, not {observation_space}")
    return ObservationStack(frames, observation_space)


def _residual_of(path, run: dict, run_file, env_id: str, observation_space, action_space, *, seed):
    """The composer of a residual agent's run.json (None for a plain model), its baseline rebuilt."""
    if "residual" not in run:
        return None
    try:
        spec = ResidualSpec.from_json(run["residual"])
        return make_composer(spec, env_id, observation_space, action_space, seed=seed)
    except ValueError as exc:
        raise TrainedModelError(f"{path}: {run_file}: bad residual entry ({exc})") from None


def load_trained_policy(
    path: str | os.PathLike,
    env_id: str,
    observation_space: spaces.Space,
    action_space: spaces.Space,
    seed: int | None = None,
    **kwargs,
) -> TrainedPolicy:
    """Load the model at ``path`` (a training directory or a ``.zip``) for ``env_id`` and check it fits.

    ``seed`` seeds a residual agent's baseline where it is stochastic (as :func:`baselines.make_policy` seeds it).
    Raises :class:`TrainedModelError` (one line) for a missing path, a corrupt model, a run.json for another
    environment id, normalisation statistics of another shape, or spaces that do not match the environment's.
    """
    if kwargs:
        raise TrainedModelError(f"{path}: a trained model takes no parameters, got {sorted(kwargs)}")
    model_file, normalize_file, run_file = resolve_model_files(path)
    run = read_run_info(run_file)
    trained_on, env_id = _bare_id(run.get("env_id")), _bare_id(env_id)
    if trained_on is not None and trained_on != env_id:
        raise TrainedModelError(f"{path}: trained on {trained_on} ({run_file}), not {env_id}")
    if normalize_file is None and _normalize_requested(run):
        raise TrainedModelError(f"{path}: {run_file} says it trained with normalize, but there is no {NORMALIZE_FILE}")
    residual = _residual_of(path, run, run_file, env_id, observation_space, action_space, seed=seed)
    if residual is not None:  # the model sees and does what the residual wrapper gave it
        observation_space, action_space = residual.observation_space, residual.action_space
    stack = _stack_of(path, run, run_file, observation_space)
    if stack is not None:  # the model (and its statistics) saw the stacked observations
        observation_space = stack.stacked_space
    model, algo = _load_model(model_file, run.get("algo"))
    for what, theirs, ours in (
        ("observations", model.observation_space, observation_space),
        ("actions", model.action_space, action_space),
    ):
        if not _same_space(theirs, ours):
            raise TrainedModelError(
                f"{path}: the model's {what} are {_space_text(theirs)}, but {env_id} has {_space_text(ours)}"
            )
    normalization = _load_normalization(normalize_file, observation_space) if normalize_file is not None else None
    checksum = model_checksum(model_file, normalize_file)
    return TrainedPolicy(
        model, algo, path, normalization=normalization, run=run, checksum=checksum, residual=residual, stack=stack
    )
