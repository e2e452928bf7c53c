"""Every environment tells its paper's algorithm from random on its task score, over the committed reference.

On every registry row the reference results (``benchmarks/results/``, what ``polyenvs leaderboard
--update-reference`` writes and the committed table reads) hold random and the paper's algorithm (or the row's
upper anchor, where the paper's policy is random by design), both with the score's metric in every episode, and
the anchor's 95% stratified bootstrap interval of the score's aggregate (IQM, or the mean of a success rate) lies
clear of random's, on the anchor's side. A row superseded by a newer version (``superseded_by``: kept registered
unchanged for the results made with it) is ranked on its successor, which must be a row of its own.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from baselines import paper_policy
from polyenvs.commands.leaderboard import REFERENCE_RESULTS_DIR
from polyenvs.evaluation.results import stored_results
from polyenvs.evaluation.table import leaderboard_tables
from polyenvs.registry import REGISTRY

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tables() -> dict[str, dict]:
    docs = stored_results([row.id for row in REGISTRY], ROOT / REFERENCE_RESULTS_DIR, progress=lambda _: None)
    return leaderboard_tables(docs)


@pytest.mark.parametrize("row", REGISTRY, ids=lambda row: row.id)
def test_the_paper_beats_random_on_the_task_score(tables, row):
    if row.superseded_by is not None:  # ranked on its successor, which must itself be a row that is not superseded
        successor = {r.id: r for r in REGISTRY}.get(row.superseded_by)
        assert successor is not None and successor.superseded_by is None, f"{row.id}: bad successor"
        return
    table = tables.get(row.id)
    assert table is not None, f"no reference results for {row.id}"
    anchor = row.score.upper_anchor or paper_policy(row.id)
    found = {r["label"]: r for r in table["rows"]}
    for label in ("random", anchor):
        assert label in found, f"{row.id}: no reference result for {label}"
        assert found[label]["score"] is not None, f"{row.id}: {label}'s episodes lack the metric {row.score.metric!r}"
    rand, best = found["random"]["score"], found[anchor]["score"]
    clear = best["low"] > rand["high"] if row.score.direction == "max" else best["high"] < rand["low"]
    assert clear, (
        f"{row.id}: {anchor} {row.score.metric} {row.score.aggregate} {best['value']:.3g} [{best['low']:.3g}, {best['high']:.3g}] "
        f"against random {rand['value']:.3g} [{rand['low']:.3g}, {rand['high']:.3g}]"
    )
