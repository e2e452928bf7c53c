"""The leaderboard's page: the Markdown file, opened by the verdict, then each environment's table, and its charts.

:func:`write_leaderboard` writes the page (:func:`leaderboard_markdown`) and, beside it, the charts drawn with
matplotlib (:mod:`~polyenvs.evaluation.charts`): an interval plot of the score per environment (:func:`plot_path`)
and a performance profile over the environments (:func:`profile_path`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from polyenvs.evaluation import charts
from polyenvs.evaluation.protocol import EVAL_SEED, PROTOCOL_EPISODES
from polyenvs.evaluation.table import environment_section, leaderboard_tables
from polyenvs.evaluation.verdict import verdict_section
from polyenvs.files import write_text_atomic
from polyenvs.registry import slug

__all__ = ["leaderboard_markdown", "plot_path", "profile_path", "write_leaderboard"]


def plot_path(table: Path, env_id: str) -> Path:
    """The PNG beside the Markdown table: ``<table stem>_<env id with / as __>.png``."""
    table = Path(table)
    return table.parent / f"{table.stem}_{slug(env_id)}.png"


def profile_path(table: Path) -> Path:
    """The performance profile's PNG beside the Markdown table: ``<table stem>_profile.png``."""
    table = Path(table)
    return table.parent / f"{table.stem}_profile.png"


def _episode_counts(documents: list[dict]) -> str:
    """How many episodes each policy ran: the usual count, then the environments that ran another."""
    per_env: dict[str, set[int]] = {}
    for doc in documents:
        per_env.setdefault(doc["env_id"], set()).add(int(doc["n_episodes"]))
    counts = [n for ns in per_env.values() for n in ns]
    usual = max(set(counts), key=counts.count) if counts else 0
    others = [f"{'/'.join(map(str, sorted(ns)))} on {env_id}" for env_id, ns in per_env.items() if ns != {usual}]
    return f"{usual}" + (f" ({'; '.join(others)})" if others else "")


def leaderboard_markdown(
    documents: list[dict],
    quick: bool | None = None,
    plots: dict[str, str] | None = None,
    profile: str | None = None,
) -> str:
    """The leaderboard as Markdown: per environment, the headline table (ranked by the task score) and RL Zoo's
    columns with the task metrics in a collapsed block; with ``plots`` (env id -> PNG file name relative to the
    table) a link to each environment's interval plot, with ``profile`` to the performance profile.

    ``quick`` (the table warns that numbers are indicative) defaults to: some result has fewer than
    :data:`PROTOCOL_EPISODES` episodes.
    """
    counts = sorted({int(d["n_episodes"]) for d in documents})
    if quick is None:
        quick = any(n < PROTOCOL_EPISODES for n in counts)
    each = f"Each policy (each training seed of a trained agent): {_episode_counts(documents)} evaluation episodes"
    lines = [
        "# polyenvs leaderboard",
        "",
        f"{each} on seeds {EVAL_SEED}, {EVAL_SEED + 1}, ... (the same for every policy), deterministic actions, on "
        'the default layouts and on the held-out ones (`layouts="test"`, which no training run sees). Rows are '
        "ranked by each environment's task score (the episode metric that is its paper's task, declared on its "
        "registry row): its interquartile mean (IQM; the mean for a success rate) with a 95% stratified bootstrap "
        "interval, normalised so that "
        "random = 0 and the paper's algorithm (or a stated upper anchor) = 1, unless their intervals overlap "
        '("not discriminative"). The return\'s IQM is shown beside it. The gap is the default score minus the '
        "held-out one, in the score's units, positive where the held-out layouts are worse. A trained algorithm's "
        "row pools the episodes of all its training seeds, and its interval takes the run as the unit (a two-level "
        "bootstrap: training seeds drawn with replacement, then episodes within each); each seed's own score is "
        "in the last column.",
        "",
    ]
    if quick:
        lines += [
            f"**Quick mode**: fewer episodes than the protocol's {PROTOCOL_EPISODES}; numbers are indicative only.",
            "",
        ]
    tables = leaderboard_tables(documents)
    lines += verdict_section(tables)
    if profile:
        lines += [f"![Performance profile of the normalised task scores over the environments]({profile})", ""]
    for env_id, table in tables.items():
        lines += [f"## {env_id}", "", *environment_section(env_id, table, (plots or {}).get(env_id))]
    return "\n".join(lines)


def write_leaderboard(
    documents: list[dict], path: Path, quick: bool | None = None, progress: Callable[[str], None] = print
) -> str:
    """Write the Markdown table to ``path`` and its charts beside it (:func:`plot_path`, :func:`profile_path`),
    drawn with matplotlib (the ``plots`` extra); without it the table is written alone and ``progress`` says so."""
    path = Path(path)
    tables = leaderboard_tables(documents)
    plots, profile = {}, None
    if charts.available():
        for env_id, table in tables.items():
            charts.save(charts.interval_plot(env_id, table), plot_path(path, env_id))
            plots[env_id] = plot_path(path, env_id).name
        figure = charts.performance_profile_plot(tables)
        if figure is not None:
            charts.save(figure, profile_path(path))
            profile = profile_path(path).name
    else:
        progress(f"charts left out: they need matplotlib: {charts.INSTALL_HINT}")
    text = leaderboard_markdown(documents, quick=quick, plots=plots, profile=profile)
    write_text_atomic(path, text)
    return text
