"""The leaderboard's verdict: does a trained agent beat the paper's algorithm on layouts it never trained on?

:func:`agent_verdict` compares an environment's best trained agent with the paper's algorithm (or the row's upper
anchor) on a table of :func:`~polyenvs.evaluation.table.leaderboard_tables`, with the training run as the unit
(:func:`~polyenvs.evaluation.statistics.compare`); :func:`verdict_section` writes the answer for every environment as
the Markdown section that opens the leaderboard.
"""

from __future__ import annotations

from polyenvs.evaluation.protocol import COUNTED_TRAINING_LAYOUTS
from polyenvs.evaluation.statistics import Comparison, compare, probability_of_improvement
from polyenvs.evaluation.table import format_interval, superseded_by

__all__ = ["agent_verdict", "is_counted", "verdict_section"]

#: Which layouts' comparison the verdict counts, and which it shows beside.
_LAYOUT_KEYS = {"held_out": ("held_out_runs", "held_out_tie_runs"), "default": ("score_runs", "tie_runs")}


def _compare(agent: dict, reference: dict, score, layouts: str) -> Comparison | None:
    """The agent against the reference on ``layouts`` ("default" or "held_out"): the difference of the task score
    with its run-level interval (and of the tie-break metric where both are at the ceiling), or None without
    values on both sides."""
    runs, ties = _LAYOUT_KEYS[layouts]
    if agent[runs] is None or reference[runs] is None:
        return None
    return compare(
        agent[runs], reference[runs], score, agent_tie_groups=agent[ties], reference_tie_groups=reference[ties]
    )


def _beats(comparison: Comparison | None) -> bool:
    return comparison is not None and comparison.outcome == "better"


def is_counted(agent: dict) -> bool:
    """Whether the verdict counts an agent's row: every seed trained on the training layouts only."""
    return agent["training_layouts"] == COUNTED_TRAINING_LAYOUTS


def _tuned_reference(rows: list[dict], reference: dict) -> dict | None:
    """The row of the reference tuned on the training layouts (``polyenvs tune``), or None."""
    label = f"tuned_{reference['label']}"
    return next((r for r in rows if r["kind"] == "tuned" and r["label"] == label and r["score"] is not None), None)


def agent_verdict(table: dict) -> dict | None:
    """Whether a trained agent beats the paper's algorithm (the upper anchor where the row names one) on a table of
    :func:`~polyenvs.evaluation.table.leaderboard_tables`, with the run as the unit: ``{"reference", "agent" (the
    best agent's row), "held_out", "default" (bools: the interval of agent minus reference wholly on the better
    side, or both at the ceiling and the tie-break's difference so), "comparisons" (layouts ->
    :class:`~polyenvs.evaluation.statistics.Comparison` or None), "improvement" (P(agent > reference) on the
    held-out layouts, ``(p, low, high)``, or None), "counted" (the agent trained on the training layouts),
    "tuned" (the reference tuned on the training layouts: its row, or None), "beats_tuned" (the same rule against it
    on the held-out layouts; None without it)}``, or None without a score, a reference or an agent.

    The best agent is the first ranked that beats the reference on the held-out layouts, counted agents before
    others, then one that beats it on the default layouts, else the best ranked.
    """
    score, rows = table["score"], table["rows"]
    kind = "anchor" if score is not None and score.upper_anchor else "paper"
    reference = next((r for r in rows if r["kind"] == kind), None)
    agents = [r for r in rows if r["kind"] == "agent" and r["score"] is not None]
    if score is None or reference is None or not agents:
        return None
    tuned = _tuned_reference(rows, reference)
    verdicts = [_verdict_of(agent, reference, score, tuned) for agent in agents]
    return max(verdicts, key=lambda v: (v["counted"], v["held_out"], v["default"]))  # max keeps the first of equals


def _verdict_of(agent: dict, reference: dict, score, tuned: dict | None) -> dict:
    comparisons = {layouts: _compare(agent, reference, score, layouts) for layouts in _LAYOUT_KEYS}
    against_tuned = _compare(agent, tuned, score, "held_out") if tuned is not None else None
    improvement = None
    if agent["held_out_runs"] is not None and reference["held_out_runs"] is not None:
        improvement = probability_of_improvement(
            agent["held_out_runs"], reference["held_out_runs"], score.aggregate, score.direction
        )
    return {
        "reference": reference,
        "agent": agent,
        "held_out": _beats(comparisons["held_out"]),
        "default": _beats(comparisons["default"]),
        "comparisons": comparisons,
        "improvement": improvement,
        "counted": is_counted(agent),
        "tuned": tuned,
        "beats_tuned": None if tuned is None else _beats(against_tuned),
        "tuned_comparison": against_tuned,
    }


def _format_difference(comparison: Comparison | None) -> str:
    """``+0.04 [0.01, 0.07] (+5.0%)``: agent minus reference with its interval and relative change; the tie-break's
    difference after it where it decided."""
    if comparison is None:
        return "-"
    d = comparison.score
    text = f"{d.value:+.3g} [{d.low:.3g}, {d.high:.3g}]"
    text += f" ({100 * d.relative:+.1f}%)" if d.relative is not None else ""
    if comparison.tie_break is not None:
        tie = comparison.tie_break
        text += f"; tie-break {tie.value:+.3g} [{tie.low:.3g}, {tie.high:.3g}]"
    return text


def _format_probability(improvement: tuple[float, float, float] | None) -> str:
    return "-" if improvement is None else f"{improvement[0]:.2f} [{improvement[1]:.2f}, {improvement[2]:.2f}]"


_VERDICT_HEADER = (
    "| environment | paper's algorithm (or anchor), held-out | best trained agent, held-out (trained on) | "
    "held-out difference [95% CI] (relative) | P(agent > paper), held-out | beats it on held-out layouts | "
    "on the default layouts | paper's algorithm tuned, held-out | beats the tuned paper on held-out layouts |"
)


def verdict_section(tables: dict[str, dict]) -> list[str]:
    """The question the leaderboard answers, per environment: does a trained agent beat the paper's algorithm on
    layouts it never trained on?"""
    lines = [
        "## Does a trained agent beat the paper's algorithm?",
        "",
        'On layouts it never trained on: the held-out ones (`layouts="test"`), the default ones beside. Beats: '
        "the 95% interval of the difference of the task score, agent minus the paper's algorithm (the upper "
        "anchor, on a row that names one), lies wholly on the better side of 0, with the training run as the unit "
        "(a two-level bootstrap: training seeds, then episodes within each; the reference's episodes); or both "
        "are at the score's ceiling and the interval of the difference of the tie-break metric's mean lies wholly "
        "on its better side. P(agent > paper) is rliable's probability of improvement: the chance that a training "
        "run of the agent scores better than the paper's algorithm. Only agents trained on the training layouts "
        f'(`layouts="{COUNTED_TRAINING_LAYOUTS}"`) are counted; others are shown, labelled with what they trained on. '
        "The tuned paper is the same algorithm with its declared parameters tuned on the training layouts "
        "(`polyenvs tune`, one run per tuning seed), judged by the same rule: a trained agent that beats the paper "
        "may only have beaten its default numbers.",
        "",
        _VERDICT_HEADER,
        "|---|---|---|---|---|---|---|---|---|",
    ]
    counts = {"held": 0, "default": 0, "any_held": 0, "any_default": 0, "total": 0, "counted": 0, "tuned": 0,
              "beats_tuned": 0}  # fmt: skip
    for env_id, table in tables.items():
        verdict, successor = agent_verdict(table), superseded_by(env_id)
        counts["total"] += successor is None
        if successor is not None:
            env_id = f"{env_id} (superseded by {successor}: not counted)"
        if verdict is None:
            reference = next((r for r in table["rows"] if r["kind"] in ("paper", "anchor")), None)
            name = f"{reference['label']} {format_interval(reference['held_out'])}" if reference else "-"
            lines.append(f"| {env_id} | {name} | no trained agent | - | - | - | - | - | - |")
            continue
        if successor is None:
            _count(counts, verdict)
        lines.append("| " + " | ".join(_verdict_cells(env_id, verdict)) + " |")
    summary = (
        f"Counting agents trained on the training layouts: a trained agent beats the paper's algorithm on the "
        f"held-out layouts on {counts['held']} of the {counts['total']} environments the benchmark ranks on "
        f"({counts['counted']} have such an agent), and on the default layouts on {counts['default']}. Counting "
        f"every agent, whatever it trained on: {counts['any_held']} on the held-out layouts, "
        f"{counts['any_default']} on the default ones. Against the paper's algorithm tuned on the training layouts "
        f"(on the {counts['tuned']} of those environments with a tuned row and a counted agent): "
        f"{counts['beats_tuned']}."
    )
    return [*lines[:2], summary, "", *lines[2:], ""]


def _count(counts: dict, verdict: dict) -> None:
    counts["any_held"] += verdict["held_out"]
    counts["any_default"] += verdict["default"]
    if verdict["counted"]:
        counts["counted"] += 1
        counts["held"] += verdict["held_out"]
        counts["default"] += verdict["default"]
        if verdict["tuned"] is not None:
            counts["tuned"] += 1
            counts["beats_tuned"] += bool(verdict["beats_tuned"])


def _verdict_cells(env_id: str, verdict: dict) -> list[str]:
    ref, agent, tuned = verdict["reference"], verdict["agent"], verdict["tuned"]
    trained_on = f"{agent['training_layouts']} layouts" + ("" if verdict["counted"] else ": not counted")
    return [
        env_id,
        f"{ref['label']} {format_interval(ref['held_out'])}",
        f"{agent['label']} {format_interval(agent['held_out'])} ({trained_on})",
        _format_difference(verdict["comparisons"]["held_out"]),
        _format_probability(verdict["improvement"]),
        "**yes**" if verdict["held_out"] else "no",
        "**yes**" if verdict["default"] else "no",
        "-" if tuned is None else f"{tuned['label']} {format_interval(tuned['held_out'])}",
        "-" if tuned is None else ("**yes**" if verdict["beats_tuned"] else "no"),
    ]
