"""The leaderboard's charts, drawn with matplotlib (``pip install "polyenvs[plots]"``) the way rliable draws them.

- :func:`interval_plot`: per environment, each policy's task score as its IQM (a tick) and 95% stratified bootstrap
  interval (a bar), the default layouts above, the held-out ones below in a lighter shade, as rliable's
  ``plot_interval_estimates``.
- :func:`performance_profile_plot`: over the environments whose score is discriminative, the fraction of episodes
  whose normalised score (random 0, the paper's algorithm or upper anchor 1) exceeds tau, with its stratified
  bootstrap band, per kind of policy (random, the paper's algorithm, each trained algorithm), as rliable's
  ``plot_performance_profiles``.

Both take the tables of :func:`polyenvs.evaluation.table.leaderboard_tables` and return a matplotlib ``Figure``;
:func:`save` writes one as a PNG atomically and closes it.

- :func:`learning_curve_plot`: per environment, the task score of the training episodes against training steps,
  one colour per trained algorithm (a line per training seed), the paper's and random's evaluated levels as
  horizontal lines.
"""

from __future__ import annotations

import importlib.util
import itertools
from pathlib import Path

import numpy as np

from polyenvs.core.extras import install_hint
from polyenvs.evaluation.statistics import performance_profile
from polyenvs.files import atomic_path

__all__ = ["INSTALL_HINT", "available", "interval_plot", "learning_curve_plot", "performance_profile_plot", "save"]

INSTALL_HINT = install_hint("plots")
#: Colours by kind of row (matplotlib's tab10): random grey, the paper's algorithm blue, an upper anchor navy (both
#: can be drawn on one row), other hand baselines light blue, tuned hand baselines teal, trained agents orange.
COLOURS = {"random": "#7f7f7f", "paper": "#1f77b4", "anchor": "#08306b", "baseline": "#9ecae1", "tuned": "#1b9e77",
           "agent": "#ff7f0e"}  # fmt: skip
#: The trained algorithms' lines: tab10 without random's grey and the paper's blue, each colour solid, then
#: dash-dotted, then dotted (never dashed: a hand policy's level is), so that any number of algorithms can be drawn.
SERIES_STYLES = tuple(
    (colour, style)
    for style in ("-", "-.", ":")
    for colour in ("#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf")
)
#: Thresholds of the performance profile, in normalised score.
TAUS = np.linspace(-0.5, 2.0, 101)
#: Bootstrap samples of the profile's band (fewer than the table's 2000: a band per tau, drawn, not printed).
PROFILE_BOOTSTRAPS = 500


def available() -> bool:
    """Whether matplotlib is installed."""
    return importlib.util.find_spec("matplotlib") is not None


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed, none opened
    import matplotlib.pyplot as plt

    return plt


def interval_plot(env_id: str, table: dict):
    """The task score of each row of ``table`` (ranked, best on top): IQM tick and 95% interval bar."""
    plt = _pyplot()
    rows = [r for r in table["rows"] if r["score"] is not None]
    figure, axes = plt.subplots(figsize=(7.0, 0.9 + 0.55 * max(len(rows), 1)), layout="constrained")
    for i, row in enumerate(rows):
        y = len(rows) - 1 - i
        colour = COLOURS[row["kind"]]
        for stats, offset, alpha in ((row["score"], 0.12, 0.75), (row["held_out"], -0.18, 0.3)):
            if stats is None:
                continue
            axes.barh(y + offset, stats["high"] - stats["low"], left=stats["low"], height=0.26, color=colour,
                      alpha=alpha)  # fmt: skip
            axes.vlines(stats["value"], y + offset - 0.13, y + offset + 0.13, color="black", linewidth=2)
    ends = [v for r in rows for stats in (r["score"], r["held_out"]) if stats for v in (stats["low"], stats["high"])]
    if ends:  # padded by hand: bars stick to their edges, so an IQM at the ceiling would sit on the frame
        pad = 0.04 * (max(ends) - min(ends)) or 0.05 * max(abs(max(ends)), 1.0)
        axes.set_xlim(min(ends) - pad, max(ends) + pad)
    axes.set_yticks(range(len(rows)), [r["label"] for r in reversed(rows)])
    score = table["score"]
    axes.set_xlabel(
        f"{score.metric} ({score.aggregate.upper() if score.aggregate == 'iqm' else 'mean'}, 95% CI)"
        if score is not None
        else "task score"
    )
    held_out = any(r["held_out"] is not None for r in rows)
    subtitle = "upper bar: default layouts; lower, lighter: held-out layouts" if held_out else "default layouts"
    axes.set_title(f"{env_id}\n{subtitle}", fontsize=10)
    axes.grid(axis="x", alpha=0.3)
    axes.spines[["top", "right"]].set_visible(False)
    return figure


def _normalised_groups(tables: dict[str, dict]) -> dict[str, list[np.ndarray]]:
    """Kind of policy -> its episodes' normalised scores, one array per (environment, run), over the environments
    whose score is discriminative."""
    groups: dict[str, list[np.ndarray]] = {}
    for table in tables.values():
        rows = table["rows"]
        if not table["discriminative"]:
            continue
        anchor_kind = "anchor" if table["score"].upper_anchor else "paper"
        rand = next(r["score"]["value"] for r in rows if r["kind"] == "random")
        anchor = next(r["score"]["value"] for r in rows if r["kind"] == anchor_kind)
        for row in rows:
            name = {"random": "random", "paper": "paper's algorithm", "tuned": "tuned hand baselines"}.get(
                row["kind"], row["label"]
            )
            if row["kind"] in ("random", "paper", "tuned", "agent"):
                groups.setdefault(name, []).extend((run - rand) / (anchor - rand) for run in row["score_runs"])
    return groups


def performance_profile_plot(tables: dict[str, dict]):
    """The performance profile over ``tables``' discriminative environments, or None if there are none."""
    groups = _normalised_groups(tables)
    if not groups:
        return None
    plt = _pyplot()
    envs = sum(1 for t in tables.values() if t["discriminative"])
    figure, axes = plt.subplots(figsize=(7.0, 4.5), layout="constrained")
    series = itertools.cycle(SERIES_STYLES)
    for name, runs in groups.items():
        curve, low, high = performance_profile(runs, TAUS, n_boot=PROFILE_BOOTSTRAPS)
        kind = {"random": "random", "paper's algorithm": "paper", "tuned hand baselines": "tuned"}.get(name)
        colour, style = (COLOURS[kind], "-") if kind else next(series)
        axes.plot(TAUS, curve, color=colour, linestyle=style, linewidth=2, label=name)
        axes.fill_between(TAUS, low, high, color=colour, alpha=0.2)
    axes.set_xlabel(r"normalised task score $\tau$ (random 0, paper's algorithm 1)")
    axes.set_ylabel(r"fraction of episodes with score $> \tau$")
    axes.set_title(f"Performance profile over {envs} discriminative environment{'s' if envs != 1 else ''}", fontsize=10)
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend(frameon=False)
    axes.spines[["top", "right"]].set_visible(False)
    return figure


def learning_curve_plot(env_id: str, metric: str, curves: dict[str, list[tuple]], levels: dict[str, tuple]):
    """``curves``: algorithm -> ``(timesteps, values)`` per training seed (the window means of ``metric`` over the
    training episodes); ``levels``: a hand policy's name -> ``(its evaluated score, its kind)``, drawn across."""
    plt = _pyplot()
    figure, axes = plt.subplots(figsize=(7.0, 4.0), layout="constrained")
    for (label, seeds), (colour, style) in zip(curves.items(), itertools.cycle(SERIES_STYLES)):
        for i, (steps, values) in enumerate(seeds):
            axes.plot(steps, values, color=colour, linestyle=style, linewidth=1.5, alpha=0.8,
                      label=label if i == 0 else None)  # fmt: skip
    for name, (value, kind) in levels.items():
        axes.axhline(value, color=COLOURS[kind], linestyle="--", linewidth=1.2, label=f"{name} (evaluated)")
    axes.set_xlabel("training steps")
    axes.set_ylabel(f"{metric} (mean of the last 100 training episodes)")
    axes.set_title(f"{env_id}: learning curves, a line per training seed", fontsize=10)
    axes.grid(alpha=0.3)
    axes.legend(frameon=False, fontsize=8)
    axes.spines[["top", "right"]].set_visible(False)
    return figure


def save(figure, path: Path) -> None:
    """Write ``figure`` to ``path`` as a PNG (atomically) and close it."""
    plt = _pyplot()
    with atomic_path(Path(path)) as tmp:
        figure.savefig(tmp, format="png", dpi=100)
    plt.close(figure)
