"""The documentation's generated environment pages (docs/_ext/polyenvs_pages.py): every registry row gets one, made
from its docstring, row and spaces, with the paper and its BibTeX, the task score and the committed leaderboard
(held-out layouts and chart included); the index opens each family with a grid of recordings; the corridors'
recordings follow the robots; the citing page gives BibTeX for the software and every paper."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import polyenvs
from baselines import paper_policy
from polyenvs.registry import REGISTRY, Score, slug

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
pages = importlib.import_module("polyenvs_pages")
bibtex = importlib.import_module("polyenvs_bibtex")
pytest.importorskip("yaml", reason="CITATION.cff is read with pyyaml (the dev extra)")


@pytest.fixture(scope="module")
def left_out() -> list[str]:
    return []


@pytest.fixture(scope="module")
def tables(left_out):
    from polyenvs.evaluation.table import leaderboard_tables

    return leaderboard_tables(pages.reference_documents(ROOT, progress=left_out.append))


@pytest.fixture(scope="module")
def citation():
    return bibtex.load_citation(ROOT / "CITATION.cff")


def _page(row, tables, citation) -> str:
    if row.extra:
        pytest.importorskip(row.extra)
    chart = pages.leaderboard_chart(row.id, ROOT)
    return pages.env_page(row, tables.get(row.id), pages.PageMedia(chart=chart.name), citation)


def _reference_rows(env_id: str) -> list[tuple[str, str, str, str]]:
    """``(policy, score, held-out score, gap)`` of each row of ``env_id``'s table in the committed
    benchmarks/LEADERBOARD.md (its normalised column depends on which baseline the registry calls the paper's)."""
    text = (ROOT / "benchmarks" / "LEADERBOARD.md").read_text(encoding="utf-8")
    start = text.index(f"\n## {env_id}\n")
    table = text[text.index("| policy | score [95% CI] |", start) : text.index("<details>", start)]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in table.strip().splitlines()[2:]]
    return [(r[0], r[1], r[4], r[5]) for r in rows]


def test_a_rows_family_is_the_package_of_its_entry_point():
    """The family picks the paper a page cites (and the recording's arguments): derived from the entry point."""
    families = [row.family for row in REGISTRY]
    assert families == ["buckybot"] * 3 + ["beast"] * 8 + ["bumper"] * 4 + ["swarm"] * 5


@pytest.mark.parametrize("row", REGISTRY, ids=lambda row: row.id)
def test_every_row_has_a_page_with_its_spaces_docstring_paper_citation_and_leaderboard(row, tables, citation):
    page = _page(row, tables, citation)
    assert page.startswith(f"# `{row.id}`\n")
    for section in ("## Description", "## Action Space", "## Observation Space", "## Rewards", "## Arguments",
                    "## Version History", "## Leaderboard", "## Citation"):  # fmt: skip
        assert section in page, f"{row.id}: the page lacks {section}"
    top = page[: page.index("## Description")]  # Gymnasium's top table: the spaces and the import line
    assert re.search(r"\| Action Space[^|]*\| `\S", top) and re.search(r"\| Observation Space[^|]*\| `\S", top)
    assert f'gymnasium.make("{row.id}")' in top or f"{row.id.rpartition('.')[2]}.parallel_env()" in top
    assert "pip install polyenvs" not in page and 'pip install "polyenvs[' not in page  # not on PyPI
    assert f"../papers/{pages.PAPERS[row.family][0]}.md" in page
    reference = bibtex.find_reference(citation, pages.PAPERS[row.family][1])
    assert f"```bibtex\n{bibtex.reference_entry(reference)}\n```" in page
    assert ":class:`" not in page and ":mod:`" not in page  # reST roles are written as MyST roles
    if row.id in tables:  # the committed results' ranked rows, the paper's policy among them
        assert f"| {paper_policy(row.id)} |" in page and "Task score: `" in page


@pytest.mark.parametrize("row", REGISTRY, ids=lambda row: row.id)
def test_a_page_shows_the_committed_leaderboard_with_its_held_out_scores_and_chart(row, tables, citation, left_out):
    if row.id not in tables:
        pytest.skip(f"{row.id} has no committed results")
    assert left_out == []  # every committed result is read, the held-out layouts' and the agents' included
    page = _page(row, tables, citation)
    chart = pages.leaderboard_chart(row.id, ROOT)
    assert chart.is_file() and f"![The task score and its 95% interval per policy on {row.id}]({chart.name})" in page
    for policy, score, held_out, gap in _reference_rows(row.id):  # the numbers benchmarks/LEADERBOARD.md shows
        assert held_out != "-", f"{row.id} {policy}: the reference has no held-out score"
        line = re.compile(
            rf"^\| {re.escape(policy)} \| {re.escape(score)} \|.*\| {re.escape(held_out)} \| {re.escape(gap)} \|", re.M
        )
        assert line.search(page), f"{row.id} {policy}: the page lacks {score}, held-out {held_out}, gap {gap}"


def test_the_citing_page_gives_bibtex_for_the_software_and_every_paper(citation):
    citing = (ROOT / "docs" / "citing.md").read_text(encoding="utf-8")
    assert "```{literalinclude} environments/polyenvs.bib\n:language: bibtex\n```" in citing  # what generate() writes
    bib = bibtex.bibtex_file(citation)
    assert bib.startswith(
        "@misc{polyenvs,\n  author = {{The polyenvs authors}},\n  title = {{polyenvs: reinforcement-learning "
        "environments for unconventional, minimally-sensed robots}},\n"
        f"  note = {{Software, version {polyenvs.__version__}}},\n  year = {{2026}},\n}}"
    )
    for _, title in pages.PAPERS.values():
        reference = bibtex.find_reference(citation, title)
        entry = bibtex.reference_entry(reference)
        assert entry in bib and f"title = {{{{{title}}}}}" in entry
        assert all(author["family-names"] in entry for author in reference["authors"])
    # What the Buckybot paper's first page states: its authors, title, journal, volume, number and year.
    assert (
        "@article{grande2013buckybot,\n"
        "  author = {Grande, Robert C. and Kutzer, Michael D. M. and Brown, Christopher Y. and Armand, Mehran},\n"
        "  title = {{Buckybot: Preliminary Control and Mapping Algorithms for a Robot Geometrically Based on a "
        "Truncated Icosahedron}},\n"
        "  journal = {Johns Hopkins APL Technical Digest},\n  volume = {32},\n  number = {3},\n  year = {2013},\n}"
    ) in bib
    assert "@misc{dyemapping,\n  author = {Dye, Ken},\n  title = {{Mapping with only a bumper}},\n}" in bib


def test_the_index_opens_each_family_with_a_grid_of_recordings_linking_every_page_once():
    media = {row.id: pages.PageMedia(gif=f"{slug(row.id)}.gif") for row in REGISTRY}
    index = pages.index_page(media)
    for title in pages.FAMILY_TITLES.values():
        section = index[index.index(f"## {title}\n") :]
        assert section.index("::::{container} polyenvs-gallery") < section.index("| name | what |")
    for row in REGISTRY:
        assert index.count(f"[![{row.id}]({slug(row.id)}.gif)]({slug(row.id)}.md)") == 1
        assert index.count(f"| [`{row.id}`]({slug(row.id)}.md) |") == 1


def test_a_corridor_recording_follows_its_robots_and_keeps_its_key():
    from polyenvs.evaluation.episodes import make_agent
    from polyenvs.evaluation.rollout import episode_frames, make_env

    env = make_env("polyenvs.swarm.corridor_v0", render_mode="rgb_array")
    try:
        agent = make_agent("paper", "polyenvs.swarm.corridor_v0", env, seed=0)
        video = np.stack(episode_frames(env, agent, 0, 300, every=50))  # the robots climb 1,300 px of corridor
    finally:
        env.close()
    colours = pages.ROBOT_COLOURS["swarm"]
    map_height = pages.key_top(video[0])
    followed = pages.follow_robots(video, colours)
    window = followed.shape[1] - (video.shape[1] - map_height)
    assert followed.shape[0] == video.shape[0] and followed.shape[2] == video.shape[2]
    assert window < map_height / 2  # 631 of 1,401 rows: the first screen shows the robots, not an empty corridor
    np.testing.assert_array_equal(followed[:, window:], video[:, map_height:])  # the key, under every frame
    for frame, cut in zip(video, followed, strict=True):  # every robot pixel of every frame is inside the window
        robots = [(frame[:map_height] == c).all(axis=2).sum() for c in colours]
        assert robots == [(cut[:window] == c).all(axis=2).sum() for c in colours] and sum(robots) > 0


def test_a_recording_that_fits_its_width_is_not_cut():
    video = np.full((3, 300, 480, 3), 255, dtype=np.uint8)
    video[:, 100:110, 50:60] = pages.ROBOT_COLOURS["swarm"][0]
    assert pages.follow_robots(video, pages.ROBOT_COLOURS["swarm"]) is video


def test_the_task_score_is_shown_with_the_fields_it_sets():
    score = Score("success", "max", ceiling=1.0, aggregate="mean")
    text = pages._score_text(score)
    assert text.startswith("metric `success`, direction `max`, ceiling `1.0`") and "aggregate `mean`" in text
    assert "upper_anchor" not in text  # unset


def test_every_family_has_a_paper_page_a_citation_and_a_recording_plan(citation):
    for row in REGISTRY:
        page, title = pages.PAPERS[row.family]
        assert (ROOT / "docs" / "papers" / f"{page}.md").is_file()
        assert bibtex.find_reference(citation, title)["authors"]
        assert pages.recording_arguments(row)
