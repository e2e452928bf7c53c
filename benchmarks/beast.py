"""Beast throughput against Gymnasium's Ant-v5 and raw ``mujoco.mj_step``, as ratios measured in one run.

Targets (``benchmarks.targets``): each beast id's step costs at most ``SCALAR_TARGETS["beast_vs_raw_mj_step"]``
times a raw ``mj_step(model, data, nstep=frame_skip)`` on our own model, and runs at the ratio to Ant-v5's steps/s
(``gym.make``, which pays about 1.6x over its own raw step) of the beasts' ``gym.make`` row of ``TARGETS``.

How it is measured: every environment steps pre-sampled random actions through ``gym.make`` (resets included) in
chunks of 100 steps; before each chunk its MuJoCo state is copied to a second ``MjData``, on which the raw row
replays the same controls (the actions scaled to the joint ranges) with ``mj_step(..., nstep=frame_skip)``. Both
clocks thus run the same physics, alternating every 100 steps, and differ only by what the environment adds (for
Ant-v5, Gymnasium's ``MujocoEnv`` step). Rows are timed in rounds (order reversed every other round); each figure is
the median over rounds, each ratio the median of per-round ratios.

The native vector env (:func:`run_vector`): ``gym.make_vec(id, num_envs=8, threads=2)`` against the same 8 envs made
with ``gym.make`` and stepped one after the other in a loop (one core), on the same pre-sampled actions, alternating
every 100 steps; its target (``SCALAR_TARGETS["beast_vector_vs_single"]``) is the ratio of the two env-steps/s.

``python -m benchmarks.beast [--quick] [--ids Tumble,Roll] [--vector]``; :func:`section` returns the Markdown section
``benchmarks/throughput.py`` puts in ``THROUGHPUT.md``, :func:`run` the single envs' rows, :func:`run_vector` the
vector env's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

from benchmarks import targets
from benchmarks.peers import ANT

__all__ = ["BEAST_IDS", "VECTOR_ID", "Row", "overhead_note", "run", "run_vector", "section"]

BEAST_IDS = ("polyenvs/BeastTumble-v0", "polyenvs/BeastRoll-v0", "polyenvs/BeastTurn-v0", "polyenvs/BeastRecover-v0")
_CLASSES = {
    "polyenvs/BeastTumble-v0": ("BeastTumbleEnv", 3000),
    "polyenvs/BeastRoll-v0": ("BeastRollEnv", 8000),
    "polyenvs/BeastTurn-v0": ("BeastTurnEnv", 8000),
    "polyenvs/BeastRecover-v0": ("BeastRecoverEnv", 2000),
}
#: The id whose native vector env is timed, its envs and threads (the target's: 8 envs on 2 cores).
VECTOR_ID, VECTOR_ENVS, VECTOR_THREADS = "polyenvs/BeastRoll-v1", 8, 2
_BLOCK = 2000  # actions per block (a repeat cycles through it)
_CHUNK = 100  # steps timed between state copies


def _ensure_registered() -> None:
    """Register the beast ids here if the shared registry does not have them yet."""
    import gymnasium as gym

    import polyenvs  # noqa: F401  (registers what the registry lists)

    for env_id, (cls, steps) in _CLASSES.items():
        if env_id not in gym.registry:
            gym.register(env_id, entry_point=f"polyenvs.beast.tasks:{cls}", max_episode_steps=steps)


@dataclass
class Row:
    name: str
    setting: str
    rates: list[float] = field(default_factory=list)  # steps/s per round

    @property
    def steps_per_second(self) -> float:
        return statistics.median(self.rates)


class _Pair:
    """An environment and a raw ``mj_step`` loop on a copy of its state, timed chunk by chunk on the same physics.

    Before each chunk of ``_CHUNK`` steps the environment's MuJoCo state is copied into a second ``MjData``; the
    environment then steps the chunk's actions through ``gym.make``'s wrappers (resetting if an episode ends), and
    the raw loop replays the same controls from the copied state. Copies are outside the timers, so the two clocks
    differ only by what the environment adds to ``mj_step``.
    """

    def __init__(self, env_id: str, seed: int):
        import gymnasium as gym
        import mujoco

        self.mujoco = mujoco
        self.env = gym.make(env_id)
        self.env.reset(seed=seed)
        self.env.action_space.seed(seed)
        inner = self.env.unwrapped
        self.model, self.data, self.nstep = inner.model, inner.data, inner.frame_skip
        self.raw = mujoco.MjData(self.model)
        self.actions = [self.env.action_space.sample() for _ in range(_BLOCK)]
        if hasattr(inner, "action_to_control"):  # ours: actions in [-1, 1] scaled to the joint ranges
            self.ctrls = [inner.action_to_control(a) for a in self.actions]
        else:  # Gymnasium's MuJoCo envs take the control itself
            self.ctrls = [np.asarray(a, dtype=np.float64) for a in self.actions]

    def repeat(self, min_seconds: float) -> tuple[float, float]:
        """(environment steps/s, raw steps/s) over at least ``min_seconds`` of environment time."""
        mujoco, model, data, raw, nstep = self.mujoco, self.model, self.data, self.raw, self.nstep
        env_step, reset, mj_step, ctrl = self.env.step, self.env.reset, mujoco.mj_step, raw.ctrl
        clock = time.perf_counter
        t_env = t_raw = 0.0
        steps = 0
        while t_env < min_seconds:
            for i in range(0, _BLOCK, _CHUNK):
                mujoco.mj_copyData(raw, model, data)
                start = clock()
                for action in self.actions[i : i + _CHUNK]:
                    _, _, terminated, truncated, _ = env_step(action)
                    if terminated or truncated:
                        reset()
                t_env += clock() - start
                start = clock()
                for c in self.ctrls[i : i + _CHUNK]:
                    ctrl[:] = c
                    mj_step(model, raw, nstep=nstep)
                t_raw += clock() - start
                steps += _CHUNK
        return steps / t_env, steps / t_raw


def run(*, min_seconds: float = 2.0, rounds: int = 3, ids=BEAST_IDS, seed: int = 0) -> tuple[list[Row], list[str]]:
    """Time Ant-v5 and each beast id, each against its raw step, in interleaved rounds; rows and ratio notes."""
    _ensure_registered()
    names = ["Ant-v5", *ids]
    pairs = [_Pair(name, seed) for name in names]
    rows = {name: (Row(name, "gym.make, frame_skip 5"), Row(f"{name} raw mj_step", "nstep=5, same states and controls"))
            for name in names}  # fmt: skip
    for pair in pairs:  # warm up: numba compilation, caches
        pair.repeat(min(0.2, min_seconds))
    for r in range(rounds):
        for name, pair in (
            zip(names, pairs, strict=True) if r % 2 == 0 else reversed(list(zip(names, pairs, strict=True)))
        ):
            ours, raw = pair.repeat(min_seconds)
            rows[name][0].rates.append(ours)
            rows[name][1].rates.append(raw)
    ant, ant_raw = rows["Ant-v5"]
    notes = [
        f"Ant-v5: {ant.steps_per_second:,.0f} steps/s ({1e6 / ant.steps_per_second:.0f} µs/step through gym.make), "
        f"{statistics.median(r / a for a, r in zip(ant.rates, ant_raw.rates, strict=True)):.2f}x its raw mj_step"
    ]
    for name in ids:
        ours, raw = rows[name]
        overhead = statistics.median(r / o for o, r in zip(ours.rates, raw.rates, strict=True))
        vs_ant = statistics.median(o / a for o, a in zip(ours.rates, ant.rates, strict=True))
        notes.append(overhead_note(name, ours.steps_per_second, overhead, vs_ant))
    return [row for pair in rows.values() for row in pair], notes


class _VectorPair:
    """A native vector env and the same envs made with ``gym.make``, stepped in a loop, on the same actions."""

    def __init__(self, env_id: str, num_envs: int, threads: int, seed: int):
        import gymnasium as gym

        self.vector = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", threads=threads)
        self.singles = [gym.make(env_id) for _ in range(num_envs)]
        self.vector.reset(seed=seed)
        for i, env in enumerate(self.singles):
            env.reset(seed=seed + i)
        self.vector.action_space.seed(seed)
        self.actions = [self.vector.action_space.sample() for _ in range(_BLOCK // 4)]

    def repeat(self, min_seconds: float) -> tuple[float, float]:
        """(vector env-steps/s, single envs' env-steps/s) over at least ``min_seconds`` of the vector env's time."""
        clock, vector_step, singles = time.perf_counter, self.vector.step, self.singles
        t_vector = t_singles = 0.0
        steps = 0
        while t_vector < min_seconds:
            for i in range(0, len(self.actions), _CHUNK):
                chunk = self.actions[i : i + _CHUNK]
                start = clock()
                for actions in chunk:
                    vector_step(actions)  # it restarts an ended episode itself
                t_vector += clock() - start
                start = clock()
                for actions in chunk:
                    for env, action in zip(singles, actions, strict=True):
                        _, _, terminated, truncated, _ = env.step(action)
                        if terminated or truncated:
                            env.reset()
                t_singles += clock() - start
                steps += len(chunk) * len(singles)
        return steps / t_vector, steps / t_singles


def run_vector(
    *, min_seconds: float = 2.0, rounds: int = 3, env_id: str = VECTOR_ID, seed: int = 0
) -> tuple[list[Row], str]:
    """Time the native vector env against its envs stepped in a loop, in interleaved rounds; rows and the ratio's note."""
    _ensure_registered()
    pair = _VectorPair(env_id, VECTOR_ENVS, VECTOR_THREADS, seed)
    vector = Row(f"{env_id} native vector env", f"{VECTOR_ENVS} envs, threads={VECTOR_THREADS}: env-steps/s")
    loop = Row(f"{env_id} x {VECTOR_ENVS} via gym.make", "stepped in a loop, one core: env-steps/s")
    pair.repeat(min(0.2, min_seconds))  # warm up
    for _ in range(rounds):
        ours, theirs = pair.repeat(min_seconds)
        vector.rates.append(ours)
        loop.rates.append(theirs)
    ratio = statistics.median(v / s for v, s in zip(vector.rates, loop.rates, strict=True))
    target = targets.SCALAR_TARGETS["beast_vector_vs_single"]
    note = (
        f"{env_id} native vector env ({VECTOR_ENVS} envs, {VECTOR_THREADS} threads, {os.cpu_count()} cores here): "
        f"{ratio:.2f}x the env-steps/s of its envs stepped in a loop on one core {target.note(ratio)}"
    )
    return [vector, loop], note


def overhead_note(name: str, steps_per_second: float, overhead: float, vs_ant: float) -> str:
    """A beast id's figures against its two targets: its overhead over raw ``mj_step`` and its ratio to Ant-v5."""
    overhead_target = targets.SCALAR_TARGETS["beast_vs_raw_mj_step"]
    ant_target = targets.target_for(name, targets.Kind.MAKE).ratio_to(ANT).bound
    return (
        f"{name}: {steps_per_second:,.0f} steps/s ({1e6 / steps_per_second:.0f} µs/step); "
        f"{overhead:.3f}x the raw mj_step {overhead_target.note(overhead)}; "
        f"{vs_ant:.2f}x Ant-v5's steps/s {ant_target.note(vs_ant)}"
    )


def section(quick: bool = False) -> str:
    """The beasts' part of ``THROUGHPUT.md`` (Markdown): every row of :func:`run`, then the ratios to the targets."""
    seconds, rounds = (0.3, 2) if quick else (2.0, 3)
    rows, notes = run(min_seconds=seconds, rounds=rounds)
    vector_rows, vector_note = run_vector(min_seconds=seconds, rounds=rounds)
    rows, notes = rows + vector_rows, [*notes, vector_note]
    lines = [
        "## Platonic beasts (`python -m benchmarks.beast`)",
        "",
        "Random actions through `gym.make`, each environment alternating every 100 steps with raw",
        "`mj_step(nstep=frame_skip)` on a copy of its own MuJoCo state (same physics on both clocks); the native",
        f"vector env of {VECTOR_ID} ({VECTOR_ENVS} envs, {VECTOR_THREADS} threads) alternating with its envs stepped in "
        "a loop.",
        "",
        "| row | setting | steps/s (median of rounds) |",
        "| --- | --- | ---: |",
        *(f"| {row.name} | {row.setting} | {row.steps_per_second:,.0f} |" for row in rows),
        "",
        *(f"- {note}" for note in notes),
    ]
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="0.3 s per repeat, 2 rounds")
    parser.add_argument("--ids", default="", help="comma-separated substrings of the beast ids to time")
    parser.add_argument("--vector", action="store_true", help="only the native vector env against its envs")
    args = parser.parse_args(argv)
    seconds, rounds = (0.3, 2) if args.quick else (2.0, 3)
    if args.vector:
        rows, note = run_vector(min_seconds=seconds, rounds=rounds)
        for row in rows:
            print(f"| {row.name} | {row.setting} | {row.steps_per_second:,.0f} |")
        print(f"- {note}")
        return
    ids = [i for i in BEAST_IDS if not args.ids or any(s in i for s in args.ids.split(","))]
    if len(ids) == len(BEAST_IDS):
        print(section(args.quick))
        return
    rows, notes = run(min_seconds=seconds, rounds=rounds, ids=ids)
    for row in rows:
        print(f"| {row.name} | {row.setting} | {row.steps_per_second:,.0f} |")
    for note in notes:
        print(f"- {note}")


if __name__ == "__main__":
    main()
