"""Beast throughput against Gymnasium's Ant-v5 and raw ``mujoco.mj_step``, as ratios measured in one run.

Targets (``spec/performance.md``): each beast id's step costs at most 1.15x a raw ``mj_step(model, data,
nstep=frame_skip)`` on our own model, and runs at least as many steps per second as Ant-v5 (``gym.make``, which
pays about 1.6x over its own raw step).

How it is measured: every row steps pre-sampled random actions for at least ``min_seconds`` per repeat, resets
included, and the rows are timed in interleaved rounds (serpentine order), so drift on a shared machine cancels in
the per-round ratios, whose median is reported. The raw rows replay the same action block on the same model from the
same start state: ``data.ctrl`` = the actions scaled to the joint ranges, one ``mj_step(..., nstep=frame_skip)``,
and a reset (``mj_resetData`` + the env's start state) wherever the environment's episode ended, so both do the same
physics and differ only by what the environment adds. Ant's raw row does the same with Ant's model.

``python -m benchmarks.beast [--quick] [--ids Tumble,Roll]``; :func:`run` returns the rows for
``benchmarks/throughput.py``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BEAST_IDS", "Row", "run"]

BEAST_IDS = ("polyenvs/BeastTumble-v0", "polyenvs/BeastRoll-v0", "polyenvs/BeastTurn-v0", "polyenvs/BeastRecover-v0")
_CLASSES = {
    "polyenvs/BeastTumble-v0": ("BeastTumbleEnv", 3000),
    "polyenvs/BeastRoll-v0": ("BeastRollEnv", 8000),
    "polyenvs/BeastTurn-v0": ("BeastTurnEnv", 8000),
    "polyenvs/BeastRecover-v0": ("BeastRecoverEnv", 2000),
}
_BLOCK = 2000  # actions per block (a repeat cycles through it)


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


class _EnvLoop:
    """``gym.make(env_id)`` stepped through a block of random actions, reset when an episode ends."""

    def __init__(self, env_id: str, seed: int):
        import gymnasium as gym

        self.env = gym.make(env_id)
        self.env.reset(seed=seed)
        self.env.action_space.seed(seed)
        self.actions = [self.env.action_space.sample() for _ in range(_BLOCK)]
        self.seed = seed
        self.ends: list[int] = []  # indices after which the episode ended (for the raw replay)

    def repeat(self, min_seconds: float) -> float:
        env, actions = self.env, self.actions
        env.reset(seed=self.seed)
        self.ends = []
        steps, start = 0, time.perf_counter()
        while True:
            for i, action in enumerate(actions):
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    env.reset()
                    self.ends.append(i)
            steps += len(actions)
            elapsed = time.perf_counter() - start
            if elapsed >= min_seconds:
                return steps / elapsed


class _RawLoop:
    """Raw ``mj_step(nstep=frame_skip)`` on the same model, replaying an env loop's actions and resets."""

    def __init__(self, loop: _EnvLoop):
        import mujoco

        self.mujoco = mujoco
        self.loop = loop
        env = loop.env.unwrapped
        self.model, self.data, self.frame_skip = env.model, env.data, env.frame_skip
        if hasattr(env, "_low"):  # ours: actions in [-1, 1] scaled to the joint ranges
            self.ctrls = [env._low + (np.asarray(a, dtype=np.float64) + 1) / 2 * env._span for a in loop.actions]
        else:  # Gymnasium's MuJoCo envs take the control itself
            self.ctrls = [np.asarray(a, dtype=np.float64) for a in loop.actions]

    def repeat(self, min_seconds: float) -> float:
        mujoco, model, data, nstep = self.mujoco, self.model, self.data, self.frame_skip
        env = self.loop.env
        env.reset(seed=self.loop.seed)
        start_state = (data.qpos.copy(), data.qvel.copy())
        ends = set(self.loop.ends)
        ctrl, step = data.ctrl, mujoco.mj_step
        steps, start = 0, time.perf_counter()
        while True:
            for i, c in enumerate(self.ctrls):
                ctrl[:] = c
                step(model, data, nstep=nstep)
                if i in ends:
                    mujoco.mj_resetData(model, data)
                    data.qpos[:], data.qvel[:] = start_state
                    mujoco.mj_forward(model, data)
            steps += len(self.ctrls)
            elapsed = time.perf_counter() - start
            if elapsed >= min_seconds:
                return steps / elapsed


def run(*, min_seconds: float = 2.0, rounds: int = 3, ids=BEAST_IDS, seed: int = 0) -> tuple[list[Row], list[str]]:
    """Time Ant-v5, its raw step, each beast id and its raw step in interleaved rounds; rows and ratio notes."""
    _ensure_registered()
    loops: list[tuple[Row, object]] = []
    ant = _EnvLoop("Ant-v5", seed)
    loops.append((Row("Ant-v5", "gym.make, frame_skip 5"), ant))
    loops.append((Row("Ant-v5 raw mj_step", "nstep=5, same actions"), _RawLoop(ant)))
    for env_id in ids:
        loop = _EnvLoop(env_id, seed)
        loops.append((Row(env_id, "gym.make, frame_skip 5"), loop))
        loops.append((Row(f"{env_id} raw mj_step", "nstep=5, same actions and resets"), _RawLoop(loop)))
    for _, loop in loops:  # warm up: numba compilation, caches, and the env loops' episode ends
        if isinstance(loop, _EnvLoop):
            loop.repeat(min(0.2, min_seconds))
    for r in range(rounds):
        # An env loop records its episode ends, which its raw replay (timed next) uses: keep the pairs together.
        pairs = [(loops[i], loops[i + 1]) for i in range(0, len(loops), 2)]
        for pair in pairs if r % 2 == 0 else reversed(pairs):
            for row, loop in pair:
                row.rates.append(loop.repeat(min_seconds))
    rows = [row for row, _ in loops]
    notes = []
    ant_rates = rows[0].rates
    ant_raw = rows[1].rates
    notes.append(
        f"Ant-v5: {1e6 / rows[0].steps_per_second:.0f} µs/step through gym.make, "
        f"{statistics.median(a_raw / a for a, a_raw in zip(ant_rates, ant_raw, strict=True)):.2f}x its raw mj_step"
    )
    for i in range(2, len(rows), 2):
        ours, raw = rows[i], rows[i + 1]
        overhead = statistics.median(r / o for o, r in zip(ours.rates, raw.rates, strict=True))
        vs_ant = statistics.median(o / a for o, a in zip(ours.rates, ant_rates, strict=True))
        notes.append(
            f"{ours.name}: {ours.steps_per_second:,.0f} steps/s ({1e6 / ours.steps_per_second:.0f} µs/step); "
            f"{overhead:.3f}x the raw mj_step (target <= 1.15); {vs_ant:.2f}x Ant-v5's steps/s (target >= 1)"
        )
    return rows, notes


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="0.3 s per repeat, 2 rounds")
    parser.add_argument("--ids", default="", help="comma-separated substrings of the beast ids to time")
    args = parser.parse_args(argv)
    ids = [i for i in BEAST_IDS if not args.ids or any(s in i for s in args.ids.split(","))]
    seconds, rounds = (0.3, 2) if args.quick else (2.0, 3)
    rows, notes = run(min_seconds=seconds, rounds=rounds, ids=ids)
    print("| row | setting | steps/s (median of rounds) |")
    print("| --- | --- | ---: |")
    for row in rows:
        print(f"| {row.name} | {row.setting} | {row.steps_per_second:,.0f} |")
    print()
    for note in notes:
        print(f"- {note}")


if __name__ == "__main__":
    main()
