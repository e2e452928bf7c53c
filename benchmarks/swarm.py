"""Swarm throughput against mpe2 and VMAS, as ratios measured in one run (targets: ``benchmarks.targets``).

- agent-steps/s of a 20-robot swarm against mpe2's ``simple_spread_v3`` with N = 20 (``swarm_vs_mpe2_at_20``);
- joint steps/s of a 256-robot swarm (``swarm_joint_steps_per_s_at_256``);
- peak memory of a 256-robot swarm (``swarm_memory_mb_at_256``): ``tracemalloc`` over building, resetting and 10
  steps;
- env-steps/s of the batched swarm (:class:`polyenvs.swarm.batched.SwarmVectorEnv`, 1024 environments x 4 robots)
  against VMAS navigation with 1024 environments x 4 agents and one torch thread (``batched_swarm_vs_vmas``).

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

from benchmarks.targets import SCALAR_TARGETS

__all__ = [
    "batched_stepper",
    "format_rows",
    "measure",
    "measure_batched",
    "peak_memory_mb",
    "run",
    "section",
    "swarm_env",
    "swarm_stepper",
]

TASKS = ("obstacle_field_v0", "corridor_v0", "formation_v0")


def swarm_env(task: str, n: int):
    import importlib

    module = importlib.import_module(f"polyenvs.swarm.{task}")
    return module.parallel_env(n_robots=n, max_cycles=500)


def _mpe2(n: int):
    from mpe2 import simple_spread_v3

    return simple_spread_v3.parallel_env(N=n, max_cycles=25)


def swarm_stepper(env, seed: int = 0) -> Callable[[int], int]:
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


def batched_stepper(task: str, n_envs: int, n_robots: int, seed: int = 0) -> Callable[[int], int]:
    """``k`` steps of the batched swarm (autoresets inside); returns environment-steps."""
    from polyenvs.swarm.batched import SwarmVectorEnv

    env = SwarmVectorEnv(task, num_envs=n_envs, n_robots=n_robots)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    block = [rng.uniform(-1, 1, (env.num_envs, 2)).astype(np.float32) for _ in range(8)]

    def steps(k: int) -> int:
        for t in range(k):
            env.step(block[t % 8])
        return k * n_envs

    return steps


def _vmas_stepper(n_envs: int, n_agents: int, seed: int = 0) -> Callable[[int], int]:
    """``k`` steps of VMAS navigation (resetting when every sub-environment is done); returns environment-steps."""
    import torch
    import vmas

    torch.set_num_threads(1)  # the spec's setting: two threads run 10-100x slower on these 2-core machines
    env = vmas.make_env(scenario="navigation", num_envs=n_envs, device="cpu", continuous_actions=True,
                        n_agents=n_agents, seed=seed)  # fmt: skip
    env.reset()
    generator = torch.Generator().manual_seed(seed)
    block = [[2 * torch.rand((n_envs, 2), generator=generator) - 1 for _ in range(n_agents)] for _ in range(8)]

    def steps(k: int) -> int:
        for t in range(k):
            _, _, dones, _ = env.step(block[t % 8])
            if dones.all():
                env.reset()
            elif dones.any():
                for index in dones.nonzero().flatten().tolist():
                    env.reset_at(index)
        return k * n_envs

    return steps


def measure_batched(rounds: int = 3, seconds: float = 2.0, task: str = "obstacle_field_v0", n_envs: int = 1024,
                    n_robots: int = 4) -> list[dict]:  # fmt: skip
    """Env-steps/s of the batched swarm and of VMAS navigation at the same size, interleaved; the ratio is the
    median of per-round ratios. VMAS missing: its row says so and the ratio is absent."""
    cases = {f"batched {task} {n_envs}x{n_robots}": batched_stepper(task, n_envs, n_robots)}
    try:
        cases[f"vmas navigation {n_envs}x{n_robots}"] = _vmas_stepper(n_envs, n_robots)
    except ImportError:
        pass
    results: dict[str, list[float]] = {name: [] for name in cases}
    for r in range(rounds):
        for name in list(cases) if r % 2 == 0 else list(reversed(cases)):
            results[name].append(_rate(cases[name], seconds)[1])
    ours, *peer = list(results)
    row = {"row": ours, "env_steps_per_s": statistics.median(results[ours])}
    rows = [row]
    if peer:
        rows.append({"row": peer[0], "env_steps_per_s": statistics.median(results[peer[0]])})
        row["ratio_vs_vmas"] = statistics.median(a / b for a, b in zip(results[ours], results[peer[0]], strict=True))
    else:
        rows.append({"row": "vmas navigation: not installed (pip install vmas)", "env_steps_per_s": float("nan")})
    row["peak_memory_mb"] = _peak_memory(lambda: batched_stepper(task, n_envs, n_robots)(10))
    return rows


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


def _peak_memory(work: Callable[[], object]) -> float:
    tracemalloc.start()
    try:
        work()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def peak_memory_mb(task: str = "obstacle_field_v0", n: int = 256) -> float:
    """Peak traced memory (MB) of building a swarm, resetting it and taking 10 random steps."""
    return _peak_memory(lambda: swarm_stepper(swarm_env(task, n))(10))


def measure(rounds: int = 3, seconds: float = 2.0, tasks=TASKS) -> list[dict]:
    """The rows: per task, agent-steps/s at N = 20 with its ratio to mpe2 N = 20, joint steps/s at N = 256."""
    cases = {"mpe2 simple_spread_v3 N=20": swarm_stepper(_mpe2(20))}
    for task in tasks:
        cases[f"{task} N=20"] = swarm_stepper(swarm_env(task, 20))
        cases[f"{task} N=256"] = swarm_stepper(swarm_env(task, 256))
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
    rounds, seconds = (1, 0.5) if quick else (3, 2.0)
    return measure(rounds=rounds, seconds=seconds) + measure_batched(rounds=rounds, seconds=seconds)


def section(quick: bool = False) -> str:
    """The swarm's part of ``THROUGHPUT.md``: every row of :func:`run` against its target (Markdown)."""
    return format_rows(run(quick))


def format_rows(rows: list[dict]) -> str:
    """The rows of :func:`run` as the Markdown section, each figure with its target from ``benchmarks.targets``."""
    lines = [
        "## AP-lite swarms (`python -m benchmarks.swarm`)",
        "",
        "| row | joint steps/s | agent- or env-steps/s | ratio | peak MB |",
        "| --- | ---: | ---: | --- | ---: |",
    ]
    for row in rows:
        lines.append(_format_row(row))
    return "\n".join(lines)


def _format_row(row: dict) -> str:
    """One row of :func:`run` as a table line, each figure that has a target followed by it."""
    if "env_steps_per_s" in row:  # the batched swarm: the memory budget is the 256-robot swarm's, not its own
        ratio = _with_target(row, "ratio_vs_vmas", "{:.2f}x VMAS", "batched_swarm_vs_vmas")
        memory = f"{row['peak_memory_mb']:.1f}" if "peak_memory_mb" in row else "-"
        return f"| {row['row']} | - | {row['env_steps_per_s']:,.0f} env-steps/s | {ratio} | {memory} |"
    memory = _with_target(row, "peak_memory_mb", "{:.1f}", "swarm_memory_mb_at_256")
    if row["row"].endswith("N=256"):
        ratio = _with_target(row, "joint_steps_per_s", "{:,.0f} joint steps/s", "swarm_joint_steps_per_s_at_256")
    else:
        ratio = _with_target(row, "ratio_vs_mpe2", "{:.1f}x mpe2", "swarm_vs_mpe2_at_20")
    return (
        f"| {row['row']} | {row['joint_steps_per_s']:,.1f} | {row['agent_steps_per_s']:,.0f} agent-steps/s | "
        f"{ratio} | {memory} |"
    )


def _with_target(row: dict, key: str, text: str, target: str) -> str:
    """``row[key]`` formatted by ``text``, then ``SCALAR_TARGETS[target]``'s note on it; ``-`` without ``key``."""
    if key not in row:
        return "-"
    return f"{text.format(row[key])} {SCALAR_TARGETS[target].note(row[key])}"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="one round of 0.5 s per row")
    args = parser.parse_args(argv)
    print(section(args.quick))


if __name__ == "__main__":
    main()
