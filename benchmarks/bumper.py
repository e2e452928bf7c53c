"""Bumper cart throughput: cycles per second against CartPole-v1, and localizer updates per second.

Two rows against their targets (``benchmarks.targets``):

- ``polyenvs/BumperCartExplore-v0`` through ``gym.make``, one step = one cycle (turn, drive to the bump, back up),
  random turns, resets included: steps/s as a ratio to CartPole-v1 timed in the same rounds (the id's ``gym.make``
  row of ``TARGETS``; a time-stepped sketch managed 0.001x of CartPole);
- the bump-space Monte Carlo localizer at 1,000 particles, one update per logged cycle including its
  densest-cluster estimate, on seeded logs of the paper's arena (``SCALAR_TARGETS["localizer_updates_per_s"]``; a
  plain numpy sketch managed 47 updates/s, its feasibility model 214).

With them, what the localizer's bump-space tables (:mod:`polyenvs.bumper.bump_tables`, built once per map) cost:
their size and build time in the paper's arena and in the largest map accepted (:func:`table_lines`).

``python -m benchmarks.bumper [--quick]`` prints :func:`section`, the Markdown that ``benchmarks.throughput`` puts in
``THROUGHPUT.md``; :func:`measure` is the importable form.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

from benchmarks import targets
from benchmarks.harness import Case, Measurement, env_case, measure_rounds, paired_ratio, progress

__all__ = ["ENV_ID", "LocalizerRunner", "main", "measure", "section", "table_lines", "target_lines"]

ENV_ID = "polyenvs/BumperCartExplore-v0"
CARTPOLE = "CartPole-v1"
PARTICLES = 1000


def _ensure_registered() -> None:
    import polyenvs  # noqa: F401  (registers the ids the registry has)

    if ENV_ID not in gym.registry:  # until the registry row is in polyenvs.registry
        gym.register(ENV_ID, entry_point="polyenvs.bumper.env:BumperCartExploreEnv", max_episode_steps=200)


class LocalizerRunner:
    """Times :class:`polyenvs.estimators.bumper.BumpSpaceMCL` updates over a fixed set of logged cycles (the
    filter is reset, untimed, whenever the logs run out)."""

    num_envs = 1
    vector = False

    def __init__(self, particles: int = PARTICLES, *, min_seconds: float, seed: int = 0, runs: int = 20):
        from polyenvs.bumper.env import BumperCartExploreEnv
        from polyenvs.estimators.bumper import BumpSpaceMCL

        env = BumperCartExploreEnv()
        self.context = env.localization_context()
        rng = np.random.default_rng(seed)
        self.logs = []
        for r in range(runs):
            env.reset(seed=seed + r)
            self.logs.append([env.step(rng.uniform(-1, 1, 1).astype(np.float32))[0] for _ in range(15)])
        self.mcl = BumpSpaceMCL(particles=particles)
        self.min_seconds, self.seed = min_seconds, seed

    def warm_up(self) -> None:
        self.mcl.reset(self.context, np.zeros(3), np.random.default_rng(self.seed))
        for log in self.logs[0]:
            self.mcl.update(log)

    def timed_repeat(self) -> float:
        updates, elapsed, r = 0, 0.0, 0
        while elapsed < self.min_seconds:
            self.mcl.reset(self.context, np.zeros(3), np.random.default_rng(self.seed + r))
            logs = self.logs[r % len(self.logs)]
            start = time.perf_counter()
            for log in logs:
                self.mcl.update(log)
            elapsed += time.perf_counter() - start
            updates += len(logs)
            r += 1
        return updates / elapsed

    def close(self) -> None:
        pass


def measure(*, min_seconds: float = 2.0, repeats: int = 3, seed: int = 0) -> tuple[list[Measurement], dict]:
    """The rows (CartPole, the cart, the localizer) timed in interleaved rounds, and the two ratios."""
    _ensure_registered()
    kw = {"min_seconds": min_seconds, "seed": seed}
    cases = [
        env_case(CARTPOLE, "`gym.make`", lambda: gym.make(CARTPOLE), **kw),
        env_case(ENV_ID, "`gym.make`, one cycle per step", lambda: gym.make(ENV_ID), **kw),
        Case(
            f"BumpSpaceMCL, {PARTICLES} particles",
            "updates/s with the estimate",
            start=lambda: LocalizerRunner(min_seconds=min_seconds, seed=seed),
        ),  # fmt: skip
    ]
    rows = measure_rounds(
        cases, repeats=repeats, on_repeat=lambda i, case, rate: progress(f"{case.label}: {rate:,.0f}/s")
    )
    cartpole, cart, localizer = rows
    return rows, {
        "cycles_vs_cartpole": paired_ratio(cart, cartpole),
        "localizer_updates_per_s": localizer.steps_per_second,
    }


def section(quick: bool = False) -> str:
    """The bump-only cart's part of ``THROUGHPUT.md``: its rows and the two targets (Markdown)."""
    rows, ratios = measure(min_seconds=0.5 if quick else 2.0, repeats=1 if quick else 3)
    lines = [
        "## The bump-only cart (`python -m benchmarks.bumper`)",
        "",
        "| row | setting | steps/s | µs/step | peak MB |",
        "| --- | --- | ---: | ---: | ---: |",
    ]
    for row in rows:
        memory = f"{row.peak_memory_mb:.2f}" if row.peak_memory_mb is not None else "-"
        lines.append(f"| {row.name} | {row.setting} | {row.steps_per_second:,.0f} | {row.us_per_step:.1f} | {memory} |")
    return "\n".join([*lines, "", *target_lines(ratios), *table_lines()])


def target_lines(ratios: dict) -> list[str]:
    """The two figures of :func:`measure` against their targets, as Markdown list items."""
    cart_target = targets.target_for(ENV_ID, targets.Kind.MAKE).ratio_to(CARTPOLE).bound
    ratio = ratios["cycles_vs_cartpole"]
    updates = ratios["localizer_updates_per_s"]
    localizer_target = targets.SCALAR_TARGETS["localizer_updates_per_s"]
    return [
        f"- cart cycles vs CartPole-v1: {ratio:.2f}x {cart_target.note(ratio)}" if ratio is not None else "- no ratio",
        f"- localizer updates/s at {PARTICLES} particles: {updates:,.0f} {localizer_target.note(updates)}",
    ]


def _largest_map():
    """A map as large as any accepted: a 20 m room with 63 boxes, 256 edges in all."""
    from polyenvs.bumper.maps import MAX_EXTENT_CM, MAX_SEGMENTS, BumperMap

    side, boxes = MAX_EXTENT_CM, (MAX_SEGMENTS - 4) // 4
    polygons = [[(0.0, 0.0), (side, 0.0), (side, side), (0.0, side)]]
    for i in range(boxes):
        x, y = 30.0 + (i % 8) * 245.0, 30.0 + (i // 8) * 245.0
        polygons.append([(x, y), (x + 20.0, y), (x + 20.0, y + 20.0), (x, y + 20.0)])
    return BumperMap(polygons, name="largest")


def table_lines() -> list[str]:
    """The bump-space table of the paper's arena and of the largest map accepted: cells, size, build time (the
    fastest of three builds after a compiling one), as Markdown list items."""
    from polyenvs.bumper.env import BumperCartExploreEnv
    from polyenvs.bumper.maps import make_map
    from polyenvs.estimators.bumper import BumpSpaceMCL

    mcl = BumpSpaceMCL(PARTICLES)
    mcl.configure(BumperCartExploreEnv().localization_context())
    lines = []
    for world in (make_map("paper"), _largest_map()):
        table = mcl.make_table(world.bounds)
        times = []
        for _ in range(4):
            start = time.perf_counter()
            table.install(0, world.walls)
            times.append(time.perf_counter() - start)
        nx, ny = table.codes.shape[1:]
        lines.append(
            f"- bump-space table, {world.name} map ({len(world.segments)} walls): {nx} x {ny} cells of"
            f" {table.cell_cm:.2f} cm, {table.codes.nbytes / 1e6:.2f} MB, built in {min(times[1:]) * 1e3:,.1f} ms"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 repeat of 0.5 s per row instead of 3 of 2 s")
    args = parser.parse_args(argv)
    print(section(args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
