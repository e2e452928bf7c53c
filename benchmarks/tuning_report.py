"""The tuned hand baselines, against the paper's and the best trained agent: ``python -m benchmarks.tuning_report``.

For every environment with tuned baselines committed at ``benchmarks/agents/<env>/tuned_<baseline>/seed<N>/``
(``polyenvs tune``'s directories), writes ``benchmarks/TUNING.md``: the parameters each tuning seed chose next to
the paper's, its trials and wall clock, and from the leaderboard's results the task score of the baseline as it
ships, of its tuned version (per tuning seed and pooled, the tuning run as the unit) and of the best trained agent,
on the default and the held-out layouts, with the differences that the verdict's rule judges.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from polyenvs.evaluation.agents import TUNED, find_agents
from polyenvs.evaluation.results import stored_results
from polyenvs.evaluation.statistics import compare
from polyenvs.evaluation.table import format_interval, leaderboard_tables
from polyenvs.evaluation.verdict import agent_verdict
from polyenvs.files import write_text_atomic
from polyenvs.registry import ALL_IDS, entry

__all__ = ["main"]

HERE = Path(__file__).resolve().parent


def _parameters_table(agents) -> list[str]:
    """A row per tuning seed: its chosen parameters (the paper's in the header), trials, wall clock."""
    first = agents[0].run
    names = list(first["params"])
    header = " | ".join(f"{n} (paper {first['paper_params'][n]:.4g})" for n in names)
    lines = [f"| tuning seed | {header} | trials (finished) | wall clock |", "|---" * (len(names) + 3) + "|"]
    for agent in agents:
        run = agent.run
        values = " | ".join(f"{run['params'][n]:.4g}" for n in names)
        lines.append(f"| {agent.seed} | {values} | {run['trials']} ({run['finished_trials']}) | "
                     f"{run['wall_clock_s']:.0f} s |")  # fmt: skip
    return lines


def _difference(a: dict | None, b: dict | None, score, runs: str) -> str:
    """``a - b`` on ``runs`` ("score_runs" or "held_out_runs") with its run-level interval and the verdict's word."""
    if a is None or b is None or a[runs] is None or b[runs] is None:
        return "-"
    comparison = compare(a[runs], b[runs], score)
    d = comparison.score
    return f"{d.value:+.3g} [{d.low:.3g}, {d.high:.3g}] ({comparison.outcome})"


def _scores_table(table: dict, label: str) -> list[str]:
    """The paper's baseline (or the anchor), its tuned row and the best agent: scores and differences."""
    score, rows = table["score"], table["rows"]
    base = next(r for r in rows if r["label"] == label.removeprefix(f"{TUNED}_"))
    tuned = next(r for r in rows if r["label"] == label)
    verdict = agent_verdict(table)
    agent = verdict["agent"] if verdict is not None else None
    per_seed = "; ".join(", ".join(f"{v:.3g}" for v in values or []) for values in
                         (tuned["seed_scores"], tuned["held_out_seed_scores"]))  # fmt: skip
    lines = [
        "| | default layouts | held-out layouts | per tuning seed (default; held-out) |",
        "|---|---|---|---|",
        f"| {base['label']} as it ships | {format_interval(base['score'])} | {format_interval(base['held_out'])} | - |",
        f"| {label} | {format_interval(tuned['score'])} | {format_interval(tuned['held_out'])} | {per_seed} |",
    ]
    if agent is not None:
        lines.append(f"| best agent: {agent['label']} | {format_interval(agent['score'])} | "
                     f"{format_interval(agent['held_out'])} | - |")  # fmt: skip
    lines += [
        f"| tuned minus as shipped | {_difference(tuned, base, score, 'score_runs')} | "
        f"{_difference(tuned, base, score, 'held_out_runs')} | |",
    ]
    if agent is not None:
        lines.append(f"| best agent minus tuned | {_difference(agent, tuned, score, 'score_runs')} | "
                     f"{_difference(agent, tuned, score, 'held_out_runs')} | |")  # fmt: skip
    return lines


def report(agents_dir: Path, results_dir: Path) -> str:
    lines = [
        "# The papers' algorithms, tuned",
        "",
        "Written by `python -m benchmarks.tuning_report` from the tuned baselines in `benchmarks/agents` "
        "(`polyenvs tune`, on the training layouts) and the leaderboard's results. Differences: the interval of the "
        "difference of the task score with the training (tuning) run as the unit, and the verdict's word for it.",
        "",
    ]
    for env_id in ALL_IDS:
        tuned = [a for a in find_agents(agents_dir, env_id) if a.algo == TUNED]
        if not tuned:
            continue
        docs = stored_results([env_id], results_dir, progress=lambda _: None, agents_dir=agents_dir)
        table = leaderboard_tables(docs).get(env_id)
        lines += [f"## {env_id}", "", f"Task score: `{entry(env_id).score.metric}`.", ""]
        for label in dict.fromkeys(a.label for a in tuned):
            group = [a for a in tuned if a.label == label]
            lines += [*_parameters_table(group), ""]
            if table is not None and any(r["label"] == label for r in table["rows"]):
                lines += [*_scores_table(table, label), ""]
            else:
                lines += ["Not evaluated yet: `polyenvs leaderboard` evaluates it.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=Path, default=HERE / "agents", help="committed agents (benchmarks/agents)")
    parser.add_argument("--results", type=Path, default=HERE / "results", help="the leaderboard's results")
    parser.add_argument("--out", type=Path, default=HERE / "TUNING.md", help="the report")
    args = parser.parse_args(argv)
    for name in ("agents", "results"):
        if not getattr(args, name).is_dir():
            parser.error(f"--{name} {getattr(args, name)} is not a directory")
    write_text_atomic(args.out, report(args.agents, args.results) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
