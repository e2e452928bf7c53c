"""Learning curves of the committed agents: ``python -m benchmarks.learning_curves``.

For every environment with a trained agent whose directory holds ``curve.json`` (what ``polyenvs train`` writes at
each rollout: the training episodes' window means), draws the task score against training steps, a line per
training seed and a colour per algorithm, with the evaluated scores of random and the paper's algorithm (or the
row's upper anchor) from the leaderboard's results as horizontal lines, into ``benchmarks/LEARNING_<env>.png``, and
writes ``benchmarks/LEARNING.md`` linking them. A training curve is the training episodes (stochastic actions, the
training layouts), so it sits below what the deterministic evaluation of the same agent scores.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from polyenvs.evaluation import charts
from polyenvs.evaluation.agents import find_agents
from polyenvs.evaluation.results import stored_results
from polyenvs.evaluation.table import leaderboard_tables
from polyenvs.files import write_text_atomic
from polyenvs.registry import ALL_IDS, entry, slug

__all__ = ["main"]

HERE = Path(__file__).resolve().parent
CURVE_FILE = "curve.json"


def _curves(agents_dir: Path, env_id: str, metric: str) -> dict[str, list[tuple]]:
    """algorithm row -> ``(timesteps, values)`` of ``metric`` per training seed that wrote a curve."""
    curves: dict[str, list[tuple]] = {}
    for agent in find_agents(agents_dir, env_id):
        path = Path(agent.path) / CURVE_FILE
        if not path.is_file():
            continue
        document = json.loads(path.read_text())
        values = document["metrics"].get(metric) or [None] * len(document["timesteps"])
        pairs = [(t, v) for t, v in zip(document["timesteps"], values, strict=True) if v is not None]
        if pairs:
            curves.setdefault(agent.label, []).append(tuple(zip(*pairs, strict=True)))
    return curves


def _levels(results_dir: Path, env_id: str) -> dict[str, tuple]:
    """random's and the paper's (or the upper anchor's) evaluated task score on the default layouts."""
    tables = leaderboard_tables(stored_results([env_id], results_dir, progress=lambda _: None))
    rows = tables.get(env_id, {}).get("rows", [])
    return {r["label"]: (r["score"]["value"], r["kind"]) for r in rows if r["kind"] in ("random", "paper", "anchor")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=Path, default=HERE / "agents", help="committed agents (benchmarks/agents)")
    parser.add_argument("--results", type=Path, default=HERE / "results", help="the leaderboard's results")
    parser.add_argument("--out", type=Path, default=HERE, help="where LEARNING.md and the PNGs go")
    args = parser.parse_args(argv)
    for name in ("agents", "results"):
        if not getattr(args, name).is_dir():
            parser.error(f"--{name} {getattr(args, name)} is not a directory")
    lines = ["# Learning curves", "", (__doc__ or "").split("\n\n")[1].replace("\n", " "), ""]
    for env_id in ALL_IDS:
        score = entry(env_id).score
        curves = _curves(args.agents, env_id, score.metric) if score is not None else {}
        if not curves:
            continue
        image = f"LEARNING_{slug(env_id)}.png"
        figure = charts.learning_curve_plot(env_id, score.metric, curves, _levels(args.results, env_id))
        charts.save(figure, args.out / image)
        seeds = ", ".join(
            f"{label} ({len(runs)} seed{'s' if len(runs) != 1 else ''})" for label, runs in curves.items()
        )
        lines += [f"## {env_id}", "", f"`{score.metric}`: {seeds}.", "", f"![Learning curves on {env_id}]({image})", ""]
        print(f"{env_id}: {image}")
    write_text_atomic(args.out / "LEARNING.md", "\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
