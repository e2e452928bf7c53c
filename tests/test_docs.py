"""The documentation's generated environment pages (docs/_ext/polyenvs_pages.py): every registry row gets one, made
from its docstring and row, with the paper, the task score and its committed leaderboard rows; the citation and the
changelog are where the docs include them from."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

from polyenvs.registry import REGISTRY, Score, slug

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
pages = importlib.import_module("polyenvs_pages")


@pytest.fixture(scope="module")
def tables():
    from polyenvs.leaderboard import leaderboard_tables

    return leaderboard_tables(pages.stored_documents(ROOT / "benchmarks" / "results"))


@pytest.mark.parametrize("row", REGISTRY, ids=lambda row: row.id)
def test_every_row_has_a_page_with_its_docstring_paper_and_leaderboard(row, tables):
    if row.extra:
        pytest.importorskip(row.extra)
    page = pages.env_page(row, tables.get(row.id), gif_name=None)
    assert page.startswith(f"# `{row.id}`\n")
    for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards", "## Arguments",
                    "## Version History", "## Leaderboard"):  # fmt: skip
        assert section in page, f"{row.id}: the page lacks {section}"
    assert f"../papers/{pages.PAPERS[row.family][0]}.md" in page
    assert ":class:`" not in page and ":mod:`" not in page  # reST roles are written as MyST roles
    if row.id in tables:  # the committed results' ranked rows, the paper's policy among them
        assert f"| {row.paper} |" in page and "Task score: `" in page


def test_the_index_links_every_page_once():
    index = pages.index_page()
    for row in REGISTRY:
        assert index.count(f"]({slug(row.id)}.md)") == 1


def test_the_task_score_is_shown_with_the_fields_it_sets():
    score = Score("success", "max", ceiling=1.0, aggregate="mean")
    text = pages._score_text(score)
    assert text.startswith("metric `success`, direction `max`, ceiling `1.0`") and "aggregate `mean`" in text
    assert "upper_anchor" not in text  # unset


def test_every_family_has_a_paper_page_and_a_recording_plan():
    for row in REGISTRY:
        assert (ROOT / "docs" / "papers" / f"{pages.PAPERS[row.family][0]}.md").is_file()
        assert pages.recording_arguments(row)
