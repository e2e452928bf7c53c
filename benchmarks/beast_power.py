"""The beasts' distance, tumbles and power per policy: ``python -m benchmarks.beast_power``.

The reference results were made before the beasts reported their mechanical power, so this runs, for each beast id
the benchmark ranks on (or ``--envs``), the paper's algorithm, its tuned versions (``tuned_<baseline>/seed<N>``)
and every committed agent of the row the verdict picks, on the protocol's first ``--episodes`` seeds of the default
and the held-out layouts (with ``--policy DIR`` more policies, such as a study's directory under a power limit),
and writes ``benchmarks/BEAST_POWER.md``: the means of the task score, the distance, the tumbles, the mean and peak
mechanical power and the cost of transport, per policy directory (a tuning or training seed) and layouts.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from baselines import paper_policy
from polyenvs.evaluation.agents import find_agents
from polyenvs.evaluation.episodes import evaluate
from polyenvs.evaluation.protocol import EVAL_SEED, layouts_kwargs
from polyenvs.files import write_text_atomic
from polyenvs.registry import REGISTRY, entry

__all__ = ["main"]

HERE = Path(__file__).resolve().parent
METRICS = ("distance_m", "tumbles", "mean_power_w", "peak_power_w", "cost_of_transport")


def _policies(env_id: str, agents_dir: Path, extra: list[str]) -> list[tuple[str, str]]:
    """``(name, policy)``: the paper's algorithm, then every committed tuned baseline and agent, then ``extra``."""
    found = [(f"{a.label} seed{a.seed}", a.path) for a in find_agents(agents_dir, env_id)]
    return [(str(paper_policy(env_id)), "paper"), *found, *((p, p) for p in extra)]


def _columns(env_id: str) -> list[str]:
    """The task score, then the :data:`METRICS` that are not it."""
    metric = entry(env_id).score.metric
    return [metric, *(m for m in METRICS if m != metric)]


def _row(env_id: str, name: str, policy: str, layouts: str, episodes: int) -> str:
    doc = evaluate(env_id, policy, episodes, EVAL_SEED, env_kwargs=layouts_kwargs(layouts))
    values = [np.mean([e["metrics"].get(m, np.nan) for e in doc["episodes"]]) for m in _columns(env_id)]
    return f"| {name} | {layouts} | " + " | ".join(f"{v:.3g}" for v in values) + " |"


def report(env_ids: list[str], agents_dir: Path, extra: list[str], episodes: int) -> str:
    lines = [
        "# The beasts' power",
        "",
        f"Written by `python -m benchmarks.beast_power`: means over the protocol's first {episodes} seeds "
        f"({EVAL_SEED} on). Power is the actuators' mechanical power (W: the positive part of torque times joint "
        "speed, summed over the joints, per 10 ms tick); the cost of transport is the energy over the robot's weight "
        "times the distance along the task's heading (0 where that is not positive). The paper's robot draws under "
        "12 W with all limbs moving.",
        "",
    ]
    for env_id in env_ids:
        metric, *others = _columns(env_id)
        lines += [f"## {env_id}", "", f"| policy | layouts | {metric} (score) | " + " | ".join(others) + " |",
                  "|---" * (len(others) + 3) + "|"]  # fmt: skip
        for name, policy in _policies(env_id, agents_dir, [p for p in extra if env_id.replace("/", "__") in p]):
            lines += [_row(env_id, name, policy, layouts, episodes) for layouts in ("default", "test")]
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ranked = [e.id for e in REGISTRY if e.family == "beast" and e.superseded_by is None]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=ranked, help="beast ids (default: those the benchmark ranks on)")
    parser.add_argument("--agents", type=Path, default=HERE / "agents", help="committed agents (benchmarks/agents)")
    parser.add_argument("--policy", nargs="*", default=[], help="more policy directories (named by their path, which "
                        "must contain the id with / as __)")  # fmt: skip
    parser.add_argument("--episodes", type=int, default=5, help="seeds per policy and layouts (default 5)")
    parser.add_argument("--out", type=Path, default=HERE / "BEAST_POWER.md", help="the report")
    args = parser.parse_args(argv)
    write_text_atomic(args.out, report(args.envs, args.agents, args.policy, args.episodes) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
