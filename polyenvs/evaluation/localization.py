"""Roll out seeded logs through an environment and score estimators on them (the localization benchmark).

Any Gymnasium environment can feed the benchmark if its unwrapped instance has ``localization_context()`` (what a
localizer may know: the map and the robot's nominal geometry) and its ``info`` has ``pose`` and ``pose_at_bump``
(true ``(x_cm, y_cm, heading_deg)``) and ``bumped``. The logging policy (the paper's random bounce, by default the
environment's ``"paper"`` baseline) acts on observations like any policy; the observations are the logs.

Every estimator sees the same logs (paired comparisons). Run ``r`` uses environment seed ``seed + r``, a logging
policy seeded ``seed + r`` and an estimator generator seeded ``(seed, r)``, so any single run can be repeated.

Scores after the k-th bump of each run: position error (cm) and heading error (degrees, wrapped) of the estimate
against the true pose at that bump. Failure rates over runs: ``empty_particle_set`` (some update left no
hypothesis standing, the paper's failure) and ``never_converged`` (the estimate never came within
``CONVERGED_CM`` and ``CONVERGED_DEG`` of the truth at any bump: this catches a filter locked on a mirror-like
pose while its particles survive).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from polyenvs.estimators import DEFAULT_ENV_ID, make_estimator

__all__ = ["CONVERGED_CM", "CONVERGED_DEG", "RunLog", "rollout_logs", "score_estimator", "summarize"]

#: An estimate this close to the truth (both) counts as converged.
CONVERGED_CM = 10.0
CONVERGED_DEG = 30.0
#: A run gives up after this many cycles per requested bump (a cart stuck driving into open space forever).
MAX_CYCLES_PER_BUMP = 20


@dataclass
class RunLog:
    """One seeded rollout: the logs the estimator reads and the truth it is scored against."""

    seed: int
    start_pose: np.ndarray  # (x_cm, y_cm, heading_rad)
    logs: np.ndarray  # (cycles, observation size)
    truth: np.ndarray  # (cycles, 3) pose at the end of each cycle's drive, heading in rad
    bumped: np.ndarray  # (cycles,) bool


def _pose(info_pose) -> np.ndarray:
    x, y, heading_deg = (float(v) for v in info_pose)
    return np.array([x, y, math.radians(heading_deg)])


def rollout_logs(env_id: str, runs: int, bumps: int, *, seed: int = 0, env_kwargs: dict | None = None,
                 policy: str = "paper", progress=None):  # fmt: skip
    """``(context, [RunLog])``: ``runs`` rollouts of ``env_id`` until ``bumps`` bumps each.

    Raises :class:`polyenvs.errors.InputError` for an unknown id or policy, bad keyword arguments, or an
    environment that cannot produce localization logs.
    """
    from polyenvs.errors import InputError
    from polyenvs.evaluation.episodes import make_agent, make_env
    from polyenvs.evaluation.rollout import policy_action

    env = make_env(env_id, env_kwargs)
    raw = env.unwrapped  # no time limit: a run ends at its bump count
    if not callable(getattr(raw, "localization_context", None)):
        raise InputError(f"{env_id} cannot produce localization logs (its environment has no localization_context())")
    if "budget_cycles" not in (env_kwargs or {}) and hasattr(raw, "budget_cycles"):
        # A task's budget of cycles (BumperCartExplore-v1 on) ends its episodes; a run here ends at its bump count,
        # so the budget is the run's cap. The cycles and the logs are the same whatever the budget.
        env.close()
        env = make_env(env_id, {**(env_kwargs or {}), "budget_cycles": bumps * MAX_CYCLES_PER_BUMP})
        raw = env.unwrapped
    context = raw.localization_context()
    out = []
    for r in range(runs):
        agent = make_agent(policy, env_id, env, seed=seed + r)
        if callable(getattr(agent, "seed", None)):  # hand baselines with their own generator (RandomBounce)
            agent.seed(seed + r)
        obs, info = raw.reset(seed=seed + r)
        start = _pose(info["pose"])
        logs, truth, bumped = [], [], []
        state, first = None, True
        while sum(bumped) < bumps and len(logs) < bumps * MAX_CYCLES_PER_BUMP:
            action, state = policy_action(agent, obs, state, first, info)
            first = False
            obs, _, terminated, _, info = raw.step(action)
            logs.append(np.asarray(obs, dtype=np.float64).copy())
            truth.append(_pose(info["pose_at_bump"]))
            bumped.append(bool(info["bumped"]))
            if terminated:
                break
        out.append(RunLog(seed + r, start, np.array(logs), np.array(truth).reshape(-1, 3), np.array(bumped)))
        if progress is not None:
            progress.advance()
    env.close()
    return context, out


def score_estimator(name: str, kwargs: dict, context, run_logs: list[RunLog], bumps: int, *, seed: int = 0,
                    progress=None, env_id: str = DEFAULT_ENV_ID) -> dict:  # fmt: skip
    """Run a fresh estimator per run over the logs (``name``: one of ``env_id``'s estimators or a
    ``"module:Class"``); arrays of errors after each bump, failures, and the update rate (over every run but the
    first, which pays for compiling the estimator's kernels)."""
    n = len(run_logs)
    position = np.full((n, bumps), np.nan)
    heading = np.full((n, bumps), np.nan)
    empty = np.zeros(n, dtype=bool)
    updates, seconds = 0, 0.0
    for r, run in enumerate(run_logs):
        estimator = make_estimator(name, env_id, **kwargs)
        estimator.reset(context, run.start_pose.copy(), np.random.default_rng([seed, r]))
        k = 0
        start = time.perf_counter()
        for c in range(len(run.logs)):
            estimate = np.asarray(estimator.update(run.logs[c]), dtype=np.float64)
            if estimate.shape != (3,) or not np.isfinite(estimate).all():
                raise ValueError(f"estimator {name!r} returned {estimate!r}; expected a finite (x, y, heading)")
            if run.bumped[c] and k < bumps:
                true = run.truth[c]
                position[r, k] = math.hypot(estimate[0] - true[0], estimate[1] - true[1])
                heading[r, k] = abs(math.degrees((estimate[2] - true[2] + math.pi) % (2 * math.pi) - math.pi))
                k += 1
        if r > 0 or n == 1:  # the first run pays for compilation: it is not a rate anyone sees afterwards
            seconds += time.perf_counter() - start
            updates += len(run.logs)
        empty[r] = getattr(estimator, "empty_sets", 0) > 0
        if progress is not None:
            progress.advance()
    return {"position_cm": position, "heading_deg": heading, "empty": empty, "updates": updates, "seconds": seconds}


def _quartiles(values: np.ndarray) -> dict:
    scored = ~np.isnan(values).all(axis=0)
    q = np.full((3, values.shape[1]), np.nan)
    if scored.any():
        q[:, scored] = np.nanpercentile(values[:, scored], [25, 50, 75], axis=0)
    return {
        name: [None if np.isnan(v) else round(float(v), 4) for v in row]
        for name, row in zip(("q1", "median", "q3"), q, strict=True)
    }


def summarize(result: dict) -> dict:
    """The JSON-ready summary of :func:`score_estimator`'s arrays."""
    position, heading = result["position_cm"], result["heading_deg"]
    close = (position < CONVERGED_CM) & (heading < CONVERGED_DEG)
    runs = position.shape[0]
    return {
        "position_error_cm": _quartiles(position),
        "heading_error_deg": _quartiles(heading),
        "converged_fraction": [round(float(v), 4) for v in close.mean(axis=0)],
        "failure_rates": {
            "empty_particle_set": round(float(result["empty"].mean()), 4),
            "never_converged": round(float((~close.any(axis=1)).mean()), 4),
        },
        "runs": runs,
        "runs_with_all_bumps": int((~np.isnan(position[:, -1])).sum()),
        "updates_per_s": round(result["updates"] / result["seconds"], 1) if result["seconds"] > 0 else None,
    }
