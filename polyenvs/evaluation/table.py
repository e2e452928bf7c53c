"""The leaderboard's tables: each environment's rows, ranked by its task score and normalised, and their Markdown.

:func:`leaderboard_tables` ranks each environment's rows by its task score (:class:`polyenvs.registry.Score`,
declared on its registry row): the score's interquartile mean with its 95% stratified bootstrap interval, a score
normalised so that random = 0 and the paper's algorithm (or the row's upper anchor) = 1, "not discriminative"
instead where their intervals overlap, the return's IQM beside it, and the held-out score with the gap. A trained
algorithm gets one row that pools the episodes of all its training seeds: IQM with a stratified bootstrap interval
(episodes resampled within each run), mean ``n_timesteps`` over the seeds, and the number of seeds.
:func:`environment_section` writes one environment's table as Markdown, RL Zoo's ``benchmark.md`` columns and the
task metrics in a collapsed block below it.
"""

from __future__ import annotations

import numpy as np

from polyenvs.evaluation.agents import TUNED
from polyenvs.evaluation.protocol import result_layouts
from polyenvs.evaluation.statistics import aggregate_with_two_level_ci, interquartile_mean, iqm_with_stratified_ci
from polyenvs.registry import entry

__all__ = [
    "environment_section",
    "format_interval",
    "leaderboard_rows",
    "leaderboard_tables",
    "superseded_by",
]


def _score_groups(docs: list[dict], metric: str | None) -> list[np.ndarray] | None:
    """Each run's per-episode values of ``metric`` (the task score), or None where some episode lacks it (a result
    from before the environment emitted it)."""
    if metric is None:
        return None
    groups = [np.array([e.get("metrics", {}).get(metric, np.nan) for e in d["episodes"]], float) for d in docs]
    return groups if all(np.isfinite(g).all() for g in groups) else None


def _present_groups(docs: list[dict], metric: str | None) -> list[np.ndarray] | None:
    """Each run's values of ``metric`` where its episodes report one (a tie-break metric: an episode that never
    reached the goal has no time to it), or None where no run has any."""
    if metric is None:
        return None
    groups = [np.array([e["metrics"][metric] for e in d["episodes"] if metric in e.get("metrics", {})]) for d in docs]
    groups = [g.astype(np.float64) for g in groups if g.size]
    return groups if groups and all(np.isfinite(g).all() for g in groups) else None


def _interval(groups: list[np.ndarray] | None, score) -> dict | None:
    """``{"value", "low", "high", "mean"}`` over ``groups``: the score's aggregate (IQM or mean) and its two-level
    bootstrap interval (training seeds, then episodes within each: the run is the unit, as rliable's), or None
    without values."""
    if groups is None:
        return None
    value, low, high = aggregate_with_two_level_ci(groups, score.aggregate)
    return {"value": value, "low": low, "high": high, "mean": float(np.mean(np.concatenate(groups)))}


def _seed_scores(groups: list[np.ndarray] | None, score) -> list[float] | None:
    """Each run's (training seed's) aggregate of the score, in seed order."""
    if groups is None:
        return None
    aggregate = np.mean if score.aggregate == "mean" else interquartile_mean
    return [float(aggregate(g)) for g in groups]


def _kind(label: str, agent: dict | None, env_id: str, score) -> str:
    from baselines import paper_policy

    if agent is not None:
        return "tuned" if agent.get("algo") == TUNED else "agent"
    if label == "random":
        return "random"
    if score is not None and label == score.upper_anchor:
        return "anchor"
    return "paper" if label == paper_policy(env_id) else "baseline"


def _row(env_id: str, group_key: str, docs: list[dict], held_out: list[dict], score) -> dict:
    agent = group_key.startswith("agent:")
    runs = [np.array([e["return"] for e in d["episodes"]], dtype=np.float64) for d in docs]
    iqm, low, high = iqm_with_stratified_ci(runs)
    episodes = [e for d in docs for e in d["episodes"]]
    names = sorted(set().union(*(e.get("metrics", {}).keys() for e in episodes)))
    metrics = {m: float(np.mean([e["metrics"][m] for e in episodes if m in e.get("metrics", {})])) for m in names}
    timesteps = [d["agent"].get("timesteps") for d in docs] if agent else []
    timesteps = [t for t in timesteps if isinstance(t, int | float) and not isinstance(t, bool)]
    label = group_key.removeprefix("agent:")
    metric = score.metric if score is not None else None
    tie_break = score.tie_break if score is not None else None
    layouts = {d["agent"].get("training_layouts", "default") for d in docs} if agent else set()
    return {
        "label": label,
        "kind": _kind(label, docs[0]["agent"] if agent else None, env_id, score),
        "returns": np.concatenate(runs),
        "iqm": iqm,
        "low": low,
        "high": high,
        "score_runs": _score_groups(docs, metric),
        "held_out_runs": _score_groups(held_out, metric) if held_out else None,
        "tie_runs": _present_groups(docs, tie_break),
        "held_out_tie_runs": _present_groups(held_out, tie_break) if held_out else None,
        "score": _interval(_score_groups(docs, metric), score),
        "held_out": _interval(_score_groups(held_out, metric), score) if held_out else None,
        "seed_scores": _seed_scores(_score_groups(docs, metric), score) if agent else None,
        "held_out_seed_scores": _seed_scores(_score_groups(held_out, metric), score) if agent and held_out else None,
        "training_layouts": "/".join(sorted(layouts)) if agent else None,
        "tie": metrics.get(score.tie_break) if score is not None and score.tie_break else None,
        "held_out_tie": _tie_mean(held_out, score),
        "metrics": metrics,
        "n_timesteps": float(np.mean(timesteps)) if timesteps else None,
        "seeds": [d["agent"].get("training_seed") for d in docs] if agent else None,
        "episodes": len(episodes),
    }


def _tie_mean(docs: list[dict], score) -> float | None:
    """The mean of the score's tie-break metric over ``docs``' episodes (None without one or without values)."""
    if score is None or not score.tie_break:
        return None
    values = [
        e["metrics"][score.tie_break] for d in docs for e in d["episodes"] if score.tie_break in e.get("metrics", {})
    ]
    return float(np.mean(values)) if values else None


def _overlap(a: dict, b: dict) -> bool:
    return a["low"] <= b["high"] and b["low"] <= a["high"]


def _normalise(rows: list[dict], score) -> bool:
    """Set each row's ``normalised`` score (random 0, the anchor 1) and ``gap`` (held-out minus default, worse
    positive); returns whether the anchor's interval is clear of random's (else ``normalised`` is None)."""
    rand = next((r["score"] for r in rows if r["kind"] == "random"), None)
    anchor_kind = "anchor" if score is not None and score.upper_anchor else "paper"
    anchor = next((r["score"] for r in rows if r["kind"] == anchor_kind), None)
    discriminative = rand is not None and anchor is not None and not _overlap(rand, anchor)
    for row in rows:
        s, h = row["score"], row["held_out"]
        row["normalised"] = None
        if discriminative and s is not None:
            row["normalised"] = (s["value"] - rand["value"]) / (anchor["value"] - rand["value"])
        row["gap"] = score.sign * (s["value"] - h["value"]) if s is not None and h is not None else None
    return discriminative


def _rank_key(row: dict, score) -> tuple:
    """Better rows first: by the score's IQM in its direction, then (rows at the ceiling) by the tie-break metric;
    rows without a score last, in table order."""
    s = row["score"]
    if score is None or s is None:
        return (1, 0.0, 0.0)
    at_ceiling = score.ceiling is not None and s["value"] == score.ceiling
    tie = score.tie_sign * row["tie"] if at_ceiling and row["tie"] is not None else 0.0
    return (0, -score.sign * s["value"], -tie)


def leaderboard_tables(documents: list[dict]) -> dict[str, dict]:
    """env id -> ``{"score": its :class:`~polyenvs.registry.Score` (or None), "discriminative": bool, "rows"}``.

    Rows are ranked by the task score (:func:`_rank_key`). A row: ``{"label", "kind" ("random", "paper",
    "anchor", "baseline" or "agent"), "returns" (pooled), "iqm", "low", "high" (of the return), "score" and
    "held_out" (``{"iqm", "low", "high", "mean"}`` of the score on the default and the held-out layouts, or None),
    "score_runs" (the score's values per run), "normalised" (None where not discriminative), "gap", "tie" and
    "held_out_tie" (the tie-break metric's mean on the default and the held-out layouts),
    "metrics" (means over the pooled episodes), "n_timesteps" (mean over seeds, or None), "seeds" (training seeds,
    agents only), "episodes"}``. A trained algorithm's row pools its training seeds' episodes.
    """
    by_env: dict[str, dict[str, dict[str, list[dict]]]] = {}
    for doc in documents:
        agent = doc.get("agent")
        label = agent.get("label", agent.get("algo")) if isinstance(agent, dict) else doc["policy"]
        key = ("agent:" if agent else "") + label
        by_env.setdefault(doc["env_id"], {}).setdefault(key, {}).setdefault(result_layouts(doc), []).append(doc)
    tables = {}
    for env_id, groups in by_env.items():
        score = _score_of(env_id)
        rows = [
            _row(env_id, key, layouts["default"], layouts.get("test", []), score)
            for key, layouts in groups.items()
            if "default" in layouts
        ]
        discriminative = _normalise(rows, score)
        rows.sort(key=lambda r: _rank_key(r, score))
        tables[env_id] = {"score": score, "discriminative": discriminative, "rows": rows}
    return tables


def leaderboard_rows(documents: list[dict]) -> dict[str, list[dict]]:
    """env id -> its rows, ranked (:func:`leaderboard_tables`)."""
    return {env_id: table["rows"] for env_id, table in leaderboard_tables(documents).items()}


def _score_of(env_id: str):
    try:
        return entry(env_id).score
    except KeyError:  # a result of an environment no longer (or not yet) in the registry
        return None


def _format_timesteps(n: float | None) -> str:
    """RL Zoo's style: ``1M``, ``250k``, ``1.5M``, ``256``."""
    if n is None:
        return "-"
    for unit, size in (("M", 1e6), ("k", 1e3)):
        if n >= size:
            return f"{n / size:.3g}{unit}"
    return f"{n:.0f}"


def format_interval(stats: dict | None) -> str:
    """``0.9 [0.85, 0.95]``: a score's aggregate and its interval, or "-" without one."""
    return "-" if stats is None else f"{stats['value']:.3g} [{stats['low']:.3g}, {stats['high']:.3g}]"


def _score_line(env_id: str, table: dict) -> str:
    score = table["score"]
    if score is None:
        return "No task score is declared for this environment: rows keep table order."
    words = "higher" if score.direction == "max" else "lower"
    best = "ceiling" if score.direction == "max" else "floor"
    how = "mean over episodes" if score.aggregate == "mean" else "IQM over episodes"
    line = f"Task score: `{score.metric}`, its {how} ({words} is better"
    line += f", {best} {score.ceiling:g}" if score.ceiling is not None else ""
    if score.tie_break:
        tie_words = "higher" if score.tie_direction == "max" else "lower"
        line += f"; ties at the {best}: {tie_words} `{score.tie_break}`"
    anchor = score.upper_anchor or "the paper's algorithm"
    line += f"). Normalised: random 0, {anchor} 1."
    if not table["discriminative"]:
        line += (
            f" **Not discriminative**: {anchor}'s interval overlaps random's (or one of them has no result), so no "
            "normalised score is given."
        )
    successor = superseded_by(env_id)
    if successor is not None:
        line += (
            f" **Superseded** by `{successor}`, which the benchmark ranks on; this version stays registered "
            "unchanged for the results made with it."
        )
    return line


def superseded_by(env_id: str) -> str | None:
    """The id that supersedes ``env_id`` on the benchmark, or None (also for an id no longer in the registry)."""
    try:
        return entry(env_id).superseded_by
    except KeyError:  # a result of an environment no longer (or not yet) in the registry
        return None


def _headline_table(table: dict) -> list[str]:
    lines = [
        "| policy | score [95% CI] | normalised | return IQM [95% CI] | held-out score [95% CI] | gap | "
        "per training seed (default; held-out) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in table["rows"]:
        if r["normalised"] is not None:
            normalised = f"{r['normalised']:.2f}"
        else:
            normalised = "not discriminative" if r["score"] is not None else "-"
        cells = [
            r["label"],
            format_interval(r["score"]),
            normalised,
            f"{r['iqm']:.2f} [{r['low']:.2f}, {r['high']:.2f}]",
            format_interval(r["held_out"]),
            f"{r['gap']:.3g}" if r["gap"] is not None else "-",
            _format_seed_scores(r),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _format_seed_scores(row: dict) -> str:
    """``0.98, 0.96, 0.53; 0.9, 0.8, 0.4``: each training seed's score on the default and the held-out layouts."""
    if row["seed_scores"] is None:
        return "-"
    parts = [row["seed_scores"], row["held_out_seed_scores"] or []]
    return "; ".join(", ".join(f"{v:.3g}" for v in values) for values in parts if values)


def _details_table(env_id: str, rows: list[dict]) -> list[str]:
    """RL Zoo's columns and every task metric (means), in a collapsed block below the headline table."""
    metric_names = sorted(set().union(*(r["metrics"].keys() for r in rows)) - {"return", "length"})
    header = ["algo", "env_id", "mean_reward", "std_reward", "n_timesteps", "eval_episodes", "seeds", "IQM [95% CI]"]
    lines = [
        "<details><summary>RL Zoo's columns and the task metrics (means over the default layouts' episodes)</summary>",
        "",
        "| " + " | ".join(header + metric_names) + " |",
        "|" + "---|" * (len(header) + len(metric_names)),
    ]
    for r in rows:
        returns = r["returns"]
        row = [
            r["label"],
            env_id,
            f"{returns.mean():.2f}",
            f"{returns.std():.2f}",
            _format_timesteps(r["n_timesteps"]),  # "-" for hand baselines: they are not trained
            str(len(returns)),
            str(len(r["seeds"])) if r["seeds"] is not None else "-",
            f"{r['iqm']:.2f} [{r['low']:.2f}, {r['high']:.2f}]",
        ]
        row += [f"{r['metrics'][m]:.3g}" if m in r["metrics"] else "-" for m in metric_names]
        lines.append("| " + " | ".join(row) + " |")
    return [*lines, "", "</details>"]


def environment_section(env_id: str, table: dict, plot: str | None = None) -> list[str]:
    """One environment's part of the leaderboard (a table of :func:`leaderboard_tables`), as Markdown lines: the
    score's line, the link to its interval plot (``plot``, a path relative to the page), the headline table and
    the collapsed details."""
    lines = [_score_line(env_id, table), ""]
    if plot:
        lines += [f"![The task score and its 95% interval per policy on {env_id}]({plot})", ""]
    return [*lines, *_headline_table(table), "", *_details_table(env_id, table["rows"]), ""]
