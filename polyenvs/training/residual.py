"""Training a residual agent (``polyenvs train ID --residual NAME``): a correction of a hand baseline's actions.

The agent trains on :class:`~baselines.residual.wrappers.ResidualPolicy` around each ``gym.make`` copy of the id, in
SB3's ``DummyVecEnv`` (a wrapper wraps one env, so never the native vector env, which is every copy at once): each
sub-environment runs its own baseline with its own memory. The PettingZoo swarms train on their robots (parameter
sharing, :class:`~polyenvs.training.vec_adapter.ParallelVecEnvAdapter`) with each copy wrapped in
:class:`~baselines.residual.wrappers.ParallelResidualPolicy`: one baseline per copy, a memory row per robot. A swarm's
corrections are not held (``hold`` 1): its robots leave the episode at different steps.

The model starts *at* the baseline: the last layer of its action mean is zeroed, so its deterministic action is a
zero correction and the untrained agent is the baseline, bit for bit. ``log_std`` sets the exploration noise it
starts with; a small one matters where the baseline is fragile (the beasts' gait breaks under action noise of sd
0.003, ``../shared/spec/learning.md``).
"""

from __future__ import annotations

import functools

import numpy as np

from baselines.residual import ParallelResidualPolicy, ResidualPolicy, ResidualSpec, make_composer
from polyenvs.errors import InputError

__all__ = ["MAX_LOG_STD", "MIN_LOG_STD", "check_residual", "residual_wrapper", "start_at_the_base"]

#: The range of ``log_std`` (the policy's starting log standard deviation): e^-10 to e^1.
MIN_LOG_STD, MAX_LOG_STD = -10.0, 1.0


def check_residual(spec: ResidualSpec, target, vec_env: str, log_std: float | None) -> None:
    """A residual of ``spec`` can train on ``target`` (an :class:`~polyenvs.evaluation.episodes.EnvTarget`); else InputError."""
    if target.parallel and spec.hold != 1:
        raise InputError(f"{target.env_id} is a PettingZoo swarm: its residual is not held (hold 1), got {spec.hold}")
    if vec_env == "native":
        raise InputError("a residual agent trains on wrapped single envs: it needs vec_env='dummy' or 'auto'")
    if log_std is not None and (
        isinstance(log_std, bool) or not isinstance(log_std, int | float) or not MIN_LOG_STD <= log_std <= MAX_LOG_STD
    ):
        raise InputError(f"residual_log_std must be a number in [{MIN_LOG_STD:g}, {MAX_LOG_STD:g}], got {log_std!r}")
    try:
        make_composer(spec, target.env_id, target.observation_space, target.action_space)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def residual_wrapper(spec: ResidualSpec, env_id: str, parallel: bool = False):
    """The per-env wrapper (for ``make_vec_env``'s ``wrapper_class``, or each copy of a ``parallel`` swarm) that
    makes an env a residual agent's."""
    if parallel:
        kwargs = {"baseline": spec.baseline, "scale": spec.scale, "observe_base": spec.observe_base}
        return functools.partial(ParallelResidualPolicy, env_id=env_id, **kwargs)
    return functools.partial(
        ResidualPolicy,
        baseline=spec.baseline,
        scale=spec.scale,
        observe_base=spec.observe_base,
        env_id=env_id,
        hold=spec.hold,
    )


def start_at_the_base(model, log_std: float | None = None) -> None:
    """Zero the last layer of ``model``'s action mean (its deterministic action: no correction) and, given
    ``log_std``, start its exploration there: PPO / A2C's state-independent ``log_std``, SAC / TD3's actor."""
    import torch

    policy = model.policy
    if hasattr(policy, "action_net"):  # on-policy: the mean is action_net(latent)
        layers, noise = [policy.action_net], getattr(policy, "log_std", None)
    else:  # off-policy actors: mu (and SAC's log_std layer)
        actor = policy.actor
        layers, noise = [actor.mu[-2] if isinstance(actor.mu, torch.nn.Sequential) else actor.mu], None
        if log_std is not None and hasattr(actor, "log_std"):
            with torch.no_grad():
                actor.log_std.weight.zero_()
                actor.log_std.bias.fill_(log_std)
    with torch.no_grad():
        for layer in layers:
            layer.weight.zero_()
            layer.bias.zero_()
        if log_std is not None and isinstance(noise, torch.nn.Parameter):
            noise.fill_(log_std)
    # The deterministic action of any observation is now a zero correction.
    probe = np.zeros((1, *model.observation_space.shape), dtype=model.observation_space.dtype)
    action, _ = model.predict(probe, deterministic=True)
    if np.any(action != 0):
        raise RuntimeError(f"{type(model).__name__}: zeroing the action layer left a nonzero action {action}")
