"""Evaluate a policy on an environment over fixed seeds.

The same seeds for every policy make comparisons paired; per-episode returns and task metrics (at each episode's
end: :func:`polyenvs.evaluation.rollout.final_metrics`) are kept so a leaderboard can compute any statistic later.

User input that cannot work raises :class:`~polyenvs.errors.InputError` (a ``ValueError``) before any episode runs
(a trained model's path is checked against the environment then too); policies whose ``predict`` takes
``action_masks`` (MaskablePPO models) get ``info["action_mask"]`` at every step
(:func:`polyenvs.evaluation.rollout.policy_action`), others never see it. Statistics are in
:mod:`polyenvs.evaluation.statistics`, atomic result files in :mod:`polyenvs.files`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Integral
from typing import Any

import gymnasium as gym
import numpy as np

from polyenvs.core.extras import install_hint
from polyenvs.errors import InputError, check_count, shown
from polyenvs.evaluation.rollout import run_episode, unknown_id_help
from polyenvs.limits import MAX_EPISODE_STEPS
from polyenvs.registry import bare_id

__all__ = ["EnvTarget", "evaluate", "make_agent", "make_env", "resolve_env"]


def make_env(env_id: str, env_kwargs: dict | None = None, **extra):
    """Build a Gymnasium id or a PettingZoo module path (:func:`polyenvs.evaluation.rollout.make_env`) with the user's
    ``env_kwargs``; an unknown name or a rejected keyword raises :class:`InputError`.

    ``extra`` holds the caller's own fixed arguments (``render_mode``); an error building the environment with no
    user keywords at all is not the user's doing and propagates unchanged.
    """
    from polyenvs.evaluation.rollout import UnknownEnvironment
    from polyenvs.evaluation.rollout import make_env as build

    env_kwargs = dict(env_kwargs or {})
    steps = env_kwargs.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, Integral)
                              or not 1 <= int(steps) <= MAX_EPISODE_STEPS):  # fmt: skip
        raise InputError(
            f"bad environment keyword arguments for {env_id}: max_episode_steps must be an integer from 1 to "
            f"{MAX_EPISODE_STEPS}, got {shown(repr(steps))}"
        )
    try:
        return build(env_id, env_kwargs, **extra)
    except UnknownEnvironment:
        raise _unknown(env_id) from None
    except gym.error.DependencyNotInstalled as exc:  # an extra of ours (its message names it)
        raise InputError(f"{bare_id(env_id)}: {exc}") from exc
    except ModuleNotFoundError as exc:
        from polyenvs.registry import entry

        try:
            needed_extra = entry(env_id).extra
        except KeyError:  # a user's own environment
            needed_extra = None
        hint = install_hint(needed_extra) if needed_extra else "see the README's Install section"
        raise InputError(f"{env_id} needs the package {exc.name!r}, which is not installed: {hint}") from exc
    except (TypeError, ValueError, gym.error.Error) as exc:
        if not env_kwargs:
            raise
        raise InputError(f"bad environment keyword arguments for {env_id}: {exc}") from exc


@dataclass(frozen=True)
class EnvTarget:
    """An environment name resolved once, for the layers above that build many copies of it (training): the bare
    name, the keywords it was checked with, its kind, the spaces of the policy that acts in it (one robot's, for
    a PettingZoo environment) and whether it has a native vector env."""

    env_id: str
    env_kwargs: dict
    parallel: bool
    observation_space: gym.Space
    action_space: gym.Space
    native_vector: bool


def resolve_env(env_id: str, env_kwargs: dict | None = None) -> EnvTarget:
    """Build ``env_id`` once with ``env_kwargs`` (:func:`make_env`'s errors) and keep what its users need."""
    from polyenvs.evaluation.rollout import agent_spaces, is_parallel

    env = make_env(env_id, env_kwargs)
    try:
        observation_space, action_space = agent_spaces(env)
        parallel = is_parallel(env)
    finally:
        env.close()
    name = bare_id(env_id)
    native = not parallel and gym.spec(name).vector_entry_point is not None
    return EnvTarget(name, dict(env_kwargs or {}), parallel, observation_space, action_space, native)


def _unknown(env_id: str) -> InputError:
    hint = unknown_id_help(env_id) or "neither a Gymnasium id nor a PettingZoo module path"
    return InputError(f"unknown environment id {shown(bare_id(env_id))!r}: {hint} (run 'polyenvs list' for ours)")


def make_agent(policy: str, env_id: str, env: gym.Env, seed: int | None = None, policy_kwargs: dict | None = None):
    """``baselines.make_policy`` for ``env``; an unknown policy or a rejected parameter raises :class:`InputError`.

    ``policy`` may be a trained model's path (a training directory or a ``.zip``); a missing, corrupt or mismatched
    model raises :class:`InputError` too.
    """
    from baselines import make_policy
    from polyenvs.evaluation.rollout import agent_spaces

    try:
        return make_policy(policy, env_id, *agent_spaces(env), seed=seed, **dict(policy_kwargs or {}))
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc)) from exc


def evaluate(
    env_id: str,
    policy: str = "paper",
    episodes: int = 10,
    seed: int = 0,
    *,
    env_kwargs: dict | None = None,
    policy_kwargs: dict | None = None,
    on_episode: Callable[[dict], None] | None = None,
) -> dict[str, Any]:
    """Run ``policy`` for ``episodes`` episodes seeded ``seed, seed + 1, ...``.

    Returns the document ``{"env_id", "policy", "policy_description", "seeds", "episodes": [{"seed", "return",
    "length", "metrics"}], "summary"}`` where ``summary`` holds the mean of return, length and every metric.
    ``on_episode(result)`` is called after each episode (for progress bars).
    Raises :class:`InputError` (a ``ValueError``) for unknown ids, policies, bad keyword arguments, a negative
    seed or fewer than one episode, all before any episode runs.
    """
    episodes = check_count("episodes", episodes, 1)
    seed = check_count("seed", seed, 0)
    env = make_env(env_id, env_kwargs)
    env_id = bare_id(env_id)
    try:
        agent = make_agent(policy, env_id, env, seed=seed, policy_kwargs=policy_kwargs)
        seeds = [seed + i for i in range(episodes)]
        results = []
        for s in seeds:
            results.append(run_episode(env, agent, s))
            if on_episode is not None:
                on_episode(results[-1])
    finally:
        env.close()
    summary = {
        "return": float(np.mean([r["return"] for r in results])),
        "length": float(np.mean([r["length"] for r in results])),
    }
    for key in results[0]["metrics"]:
        summary[key] = float(np.mean([r["metrics"][key] for r in results]))
    return {
        "env_id": env_id,
        "policy": os.fspath(policy),
        "policy_description": agent.describe(),
        "env_kwargs": env_kwargs or {},
        "seeds": seeds,
        "episodes": results,
        "summary": summary,
    }
