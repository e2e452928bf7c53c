"""Evaluate a policy on an environment over fixed seeds, and write results atomically.

The same seeds for every policy make comparisons paired; per-episode returns and task metrics (from
``info["episode_metrics"]``) are kept so a leaderboard can compute any statistic later.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["evaluate", "iqm_with_ci", "write_json_atomic", "write_text_atomic"]


def evaluate(
    env_id: str,
    policy: str = "paper",
    episodes: int = 10,
    seed: int = 0,
    env_kwargs: dict | None = None,
    policy_kwargs: dict | None = None,
) -> dict[str, Any]:
    """Run ``policy`` for ``episodes`` episodes seeded ``seed, seed + 1, ...``.

    Returns the document ``{"env_id", "policy", "policy_description", "seeds", "episodes": [{"seed", "return",
    "length", "metrics"}], "summary"}`` where ``summary`` holds the mean of return, length and every metric.
    Raises ``ValueError`` for unknown ids, policies or bad keyword arguments.
    """
    import polyenvs  # noqa: F401  (registers the ids)
    from baselines import make_policy

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    env_id = env_id.split(":", 1)[-1]
    if env_id not in gym.registry:
        raise ValueError(f"unknown environment id {env_id!r}; run 'polyenvs list' for the ids")
    try:
        env = gym.make(env_id, **(env_kwargs or {}))
    except TypeError as exc:
        raise ValueError(f"bad environment keyword arguments for {env_id}: {exc}") from None
    try:
        agent = make_policy(policy, env_id, env.observation_space, env.action_space, seed=seed, **(policy_kwargs or {}))
        seeds = [seed + i for i in range(episodes)]
        results = [_run_episode(env, agent, s) for s in seeds]
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
        "policy": policy,
        "policy_description": agent.describe(),
        "env_kwargs": env_kwargs or {},
        "seeds": seeds,
        "episodes": results,
        "summary": summary,
    }


def _run_episode(env: gym.Env, agent, seed: int) -> dict[str, Any]:
    obs, info = env.reset(seed=seed)
    state, start, total, length = None, True, 0.0, 0
    while True:
        action, state = agent.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        length += 1
        start = False
        if terminated or truncated:
            break
    metrics = {k: float(v) for k, v in info.get("episode_metrics", {}).items()}
    return {"seed": seed, "return": total, "length": length, "metrics": metrics}


def iqm_with_ci(values, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean and its 95% bootstrap confidence interval."""
    x = np.sort(np.asarray(values, dtype=np.float64))

    def iqm(sorted_x):
        n = sorted_x.shape[-1]
        lo, hi = int(np.floor(0.25 * n)), int(np.ceil(0.75 * n))
        return sorted_x[..., lo:hi].mean(axis=-1)

    rng = np.random.default_rng(seed)
    boots = np.sort(rng.choice(x, size=(n_boot, x.size), replace=True), axis=1)
    dist = iqm(boots)
    return float(iqm(x)), float(np.quantile(dist, 0.025)), float(np.quantile(dist, 0.975))


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a file so that a crash never leaves it half-written (temp file in the same directory + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json_atomic(path: str | os.PathLike, document: Any) -> None:
    write_text_atomic(path, json.dumps(document, indent=1) + "\n")
