"""Swarm throughput against mpe2, as ratios measured in one run (``spec/performance.md``).

- agent-steps/s of a 20-robot swarm against mpe2's ``simple_spread_v3`` with N = 20 (target >= 20x);
- joint steps/s of a 256-robot swarm (target >= 200);
- peak memory of a 256-robot swarm (target < 50 MB): ``tracemalloc`` over building, resetting and 10 steps.

Random actions, pre-sampled, passed as the PettingZoo dictionaries both environments take; resets included when
every agent is done. Rows are timed in interleaved rounds (ours and the peer alternating) and each figure is the
median over rounds; the ratio is the median of per-round ratios, so load drift on a shared machine cancels.

``python -m benchmarks.swarm [--quick]``; :func:`run` returns the rows for ``benchmarks/throughput.py``.
"""

from __future__ import annotations

import argparse
import statistics
import time
import tracemalloc
from collections.abc import Callable

import numpy as np

__all__ = ["measure", "peak_memory_mb", "run"]

TASKS = ("obstacle_field_v0", "corridor_v0", "formation_v0")


def _swarm(task: str, n: int):
    import importlib

    module = importlib.import_module(f"polyenvs.swarm.{task}")
    return module.parallel_env(n_robots=n, max_cycles=500)


def _mpe2(n: int):
    from mpe2 import simple_spread_v3

    return simple_spread_v3.parallel_env(N=n, max_cycles=25)


def _stepper(env, seed: int = 0) -> Callable[[int], int]:
    """A function that takes ``k`` joint steps (resetting when every agent is done) and returns agent-steps."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    agents = list(env.possible_agents)
    shape = env.action_space(agents[0]).shape
    discrete = not shape
    block = [
        dict(zip(agents, (rng.integers(env.action_space(agents[0]).n, size=len(agents)) if discrete
                          else rng.uniform(-1, 1, (len(agents), *shape)).astype(np.float32)), strict=True))
        for _ in range(64)
    ]  # fmt: skip

    def steps(k: int) -> int:
        done = 0
        for t in range(k):
            if not env.agents:
                env.reset()
            live = env.agents
            actions = block[t % 64]
            done += len(live)
            env.step(actions if len(live) == len(agents) else {a: actions[a] for a in live})
        return done

    return steps


def _rate(steps: Callable[[int], int], seconds: float) -> tuple[float, float]:
    """(joint steps/s, agent-steps/s) over at least ``seconds``."""
    steps(3)
    start, joint, agent = time.perf_counter(), 0, 0
    while True:
        agent += steps(10)
        joint += 10
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return joint / elapsed, agent / elapsed


def peak_memory_mb(task: str = "obstacle_field_v0", n: int = 256) -> float:
    """Peak traced memory (MB) of building a swarm, resetting it and taking 10 random steps."""
    tracemalloc.start()
    try:
        env = _swarm(task, n)
        _stepper(env)(10)
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def measure(rounds: int = 3, seconds: float = 2.0, tasks=TASKS) -> list[dict]:
    """The rows: per task, agent-steps/s at N = 20 with its ratio to mpe2 N = 20, joint steps/s at N = 256."""
    cases = {"mpe2 simple_spread_v3 N=20": _stepper(_mpe2(20))}
    for task in tasks:
        cases[f"{task} N=20"] = _stepper(_swarm(task, 20))
        cases[f"{task} N=256"] = _stepper(_swarm(task, 256))
    results: dict[str, list[tuple[float, float]]] = {name: [] for name in cases}
    for r in range(rounds):
        order = list(cases) if r % 2 == 0 else list(reversed(cases))
        for name in order:
            results[name].append(_rate(cases[name], seconds))
    peer = [agent for _, agent in results["mpe2 simple_spread_v3 N=20"]]
    rows = [{"row": "mpe2 simple_spread_v3 N=20", "joint_steps_per_s": statistics.median(j for j, _ in results["mpe2 simple_spread_v3 N=20"]),
             "agent_steps_per_s": statistics.median(peer)}]  # fmt: skip
    for task in tasks:
        for n in (20, 256):
            name = f"{task} N={n}"
            joint = [j for j, _ in results[name]]
            agent = [a for _, a in results[name]]
            row = {
                "row": name,
                "joint_steps_per_s": statistics.median(joint),
                "agent_steps_per_s": statistics.median(agent),
            }
            if n == 20:
                row["ratio_vs_mpe2"] = statistics.median(a / p for a, p in zip(agent, peer, strict=True))
            else:
                row["peak_memory_mb"] = peak_memory_mb(task, n)
            rows.append(row)
    return rows


def run(quick: bool = False) -> list[dict]:
    return measure(rounds=1 if quick else 3, seconds=0.5 if quick else 2.0)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="one round of 0.5 s per row")
    args = parser.parse_args(argv)
    for row in run(args.quick):
        extra = ""
        if "ratio_vs_mpe2" in row:
            extra = f"  {row['ratio_vs_mpe2']:.1f}x mpe2 (target >= 20x)"
        if "peak_memory_mb" in row:
            extra = f"  peak {row['peak_memory_mb']:.1f} MB (target < 50)"
        print(
            f"{row['row']:<28} {row['joint_steps_per_s']:>10.1f} joint steps/s {row['agent_steps_per_s']:>12.0f} agent-steps/s{extra}"
        )


if __name__ == "__main__":
    main()
