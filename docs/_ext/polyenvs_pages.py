"""Sphinx extension: one page per registry row, written into the source tree when the build starts.

Each page is made from what the code already holds, so no text is copied into ``docs/``: the row of
:data:`polyenvs.registry.REGISTRY` (its kind, episode limit, extra and task score) and its hand baselines
(:data:`baselines.table.BASELINES`) and estimators (:data:`polyenvs.estimators.table.ESTIMATORS`), the environment
built with its defaults (its spaces) and its class's Gymnasium-style docstring (its ``##`` sections are Markdown
already), the leaderboard section written by :func:`polyenvs.evaluation.table.environment_section` from the committed
reference results in ``benchmarks/results/`` (default and held-out layouts) with the interval chart that
``polyenvs leaderboard --update-reference`` drew beside ``benchmarks/LEADERBOARD.md``, the paper's BibTeX from
``CITATION.cff``, and a GIF of the paper's policy recorded by ``polyenvs record`` at build time. The index opens
each family with a grid of the recordings, as Gymnasium's family pages do, and ``environments/polyenvs.bib`` holds
every BibTeX entry for the citing page.

Recordings are cached in ``<build>/recordings/`` under a name that includes their recording arguments, so a
second build reuses them; delete the folder (or set ``POLYENVS_DOCS_RERECORD=1``) to record them again. A
recording taller than it is wide (the corridors) is published cut to a window that follows the robots. The
generated files live in ``docs/environments/`` (git-ignored) and are rewritten only when they change, so an
incremental build rebuilds only what changed.
"""

from __future__ import annotations

import inspect
import os
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from polyenvs_bibtex import bibtex_file, find_reference, load_citation, reference_entry

from baselines import paper_policy
from baselines.table import hand_baselines
from polyenvs.commands.leaderboard import REFERENCE_RESULTS_DIR, REFERENCE_TABLE
from polyenvs.estimators import estimators
from polyenvs.registry import REGISTRY, EnvEntry, slug
from polyenvs.swarm import rendering as swarm_rendering

#: The paper each family comes from: (its page under papers/, its title in ``CITATION.cff``'s references).
PAPERS = {
    "buckybot": (
        "buckybot",
        "Buckybot: Preliminary Control and Mapping Algorithms for a Robot Geometrically Based on a Truncated Icosahedron",
    ),
    "beast": ("beasts", "Platonic Beasts: Spherically Symmetric Multilimbed Robots"),
    "swarm": ("swarm", "Physicomimetics for Mobile Robot Obstacle Avoidance"),
    "bumper": ("bumper", "Mapping with only a bumper"),
}
FAMILY_TITLES = {
    "buckybot": "Buckybot",
    "beast": "Platonic beasts (MuJoCo)",
    "bumper": "The bump-only cart",
    "swarm": "AP-lite and physicomimetics swarms",
}

#: ``polyenvs record`` arguments per family: a few seconds of the paper's policy in small frames, so the
#: recordings, one per row, take a few minutes on two cores.
RECORDING = {
    "buckybot": ["--max-steps", "150", "--every", "3"],
    "beast": ["--max-steps", "1800", "--every", "40", "--env-kwargs", '{"width": 200, "height": 150}'],
    "bumper": ["--max-steps", "40"],
    "swarm": ["--max-steps", "900", "--every", "15"],
}
#: Where a family's arguments do not fit: a thrown beast stands up within a second.
RECORDING_BY_ID = {
    "polyenvs/BeastRecover-v0": ["--max-steps", "400", "--every", "4", "--env-kwargs", '{"width": 200, "height": 150}'],
    "polyenvs/BeastRecover-v1": ["--max-steps", "400", "--every", "4", "--env-kwargs", '{"width": 200, "height": 150}'],
}
#: The colours a family's frames draw its robots in, for recordings that follow them (:func:`follow_robots`).
ROBOT_COLOURS = {"swarm": (swarm_rendering.BODY, swarm_rendering.LEADER)}
#: Room kept above and below the robots when a recording follows them: their discs are in the span already, and
#: this shows where their IR beams point.
FOLLOW_MARGIN_PX = 48
#: The grey of the rule that :func:`polyenvs.core.raster.with_legend` draws between a frame and its key.
KEY_RULE_GREY = 200


@dataclass(frozen=True)
class PageMedia:
    """The files a page shows, beside it in ``environments/``."""

    gif: str | None = None  # the recording of the paper's policy
    followed: bool = False  # the recording is cut to a window that follows the robots
    chart: str | None = None  # the leaderboard's interval chart


def recording_arguments(row) -> list[str]:
    return RECORDING_BY_ID.get(row.id, RECORDING[row.family])


_ROLE = re.compile(r":(class|func|mod|meth|attr|data|obj|exc):`([^`]+)`")


def docstring_markdown(text: str) -> str:
    """A Gymnasium-style docstring as MyST: dedented, reStructuredText roles written as MyST roles."""
    return _ROLE.sub(r"{py:\1}`\2`", inspect.cleandoc(text))


def built_env(row) -> tuple[str, object, object]:
    """``(docstring, observation space, action space)`` of the row's environment built with its defaults (a
    parallel environment's spaces are one robot's, as ``polyenvs list`` shows them)."""
    from polyenvs.evaluation.protocol import old_versions_quietly
    from polyenvs.evaluation.rollout import agent_spaces, make_env

    with old_versions_quietly():  # a superseded -v0 is documented on purpose
        env = make_env(row.id)
    try:
        observation_space, action_space = agent_spaces(env)
        return inspect.getdoc(type(env.unwrapped)) or "", observation_space, action_space
    finally:
        env.close()


def _score_text(score) -> str:
    """The row's task score (:class:`polyenvs.registry.Score`): its fields that are set."""
    fields = {name: getattr(score, name) for name in score.__dataclass_fields__}
    return ", ".join(f"{name} `{value}`" for name, value in fields.items() if value is not None)


def install_line(row) -> str:
    """How to install what the row needs: polyenvs is not on PyPI, so from a clone (a wheel on the install page)."""
    target = f'".[{row.extra}]"' if row.extra else "."
    return f"`pip install {target}` in a clone ([or from a wheel](../install.md))"


def paper_citation(reference: dict) -> str:
    """``Grande, Kutzer, Brown and Armand, "Buckybot: ..."``: the authors' family names and the title."""
    families = [author.get("family-names", author.get("name")) for author in reference["authors"]]
    authors = families[0] if len(families) == 1 else f"{', '.join(families[:-1])} and {families[-1]}"
    return f'{authors}, "{reference["title"]}"'


def facts_table(row, spaces: tuple[object, object], reference: dict) -> list[str]:
    """The page's top table: the spaces and the import line first, as on Gymnasium's pages, then the row's facts."""
    from polyenvs.commands.list import _describe_space as describe_space

    observation_space, action_space = spaces
    policies = hand_baselines(row.id)
    names = [f"`{name}`" + (" (the paper's)" if name == policies.paper else "") for name in policies.names]
    if isinstance(row, EnvEntry):
        kind = "Gymnasium id"
        make = f'`import gymnasium, polyenvs; gymnasium.make("{row.id}")`'
        limit = f"{row.max_episode_steps} steps (`max_episode_steps`)"
        spaces_of = ""
        vector = f'`gymnasium.make_vec("{row.id}", num_envs=N)`' if row.vector_entry_point else None
    else:
        package, _, module = row.id.rpartition(".")
        kind = "PettingZoo parallel environment"
        make = f"`from {package} import {module}; {module}.parallel_env()` (AEC: `{module}.env()`)"
        limit = f"{row.max_cycles} cycles (`max_cycles`)"
        spaces_of, vector = " (each robot's)", None
    lines = [
        "| | |",
        "| --- | --- |",
        f"| Action Space{spaces_of} | `{describe_space(action_space)}` |",
        f"| Observation Space{spaces_of} | `{describe_space(observation_space)}` |",
        f"| import | {make} |",
    ]
    if vector:
        lines.append(f"| native vector env | {vector} |")
    lines += [
        f"| kind | {kind} |",
        f"| episode limit | {limit} |",
        f"| install | {install_line(row)} |",
        f"| hand baselines | {', '.join(names) or '-'} |",
        f"| task score | {_score_text(row.score)} |",
        f"| paper | [{paper_citation(reference)}](../papers/{PAPERS[row.family][0]}.md) |",
    ]
    localizers = estimators(row.id)
    if localizers:
        lines.append(
            f"| estimators | {', '.join(f'`{name}`' for name in localizers)} ([the benchmark](../guides/localization.md)) |"
        )
    return lines


def reference_documents(root: Path, progress) -> list[dict]:
    """The committed reference results (default and held-out layouts, the committed agents' included), as
    ``polyenvs leaderboard --reproduce`` reads them: ``progress`` is told of every file left out, and why."""
    from polyenvs.evaluation.agents import DEFAULT_AGENTS_DIR
    from polyenvs.evaluation.results import stored_results
    from polyenvs.registry import ALL_IDS

    return stored_results(
        ALL_IDS, root / REFERENCE_RESULTS_DIR, progress=progress, agents_dir=root / DEFAULT_AGENTS_DIR
    )


def leaderboard_section(env_id: str, table: dict | None, chart: str | None) -> list[str]:
    """The environment's part of the leaderboard, as ``polyenvs leaderboard`` writes it (ranked by the task score,
    normalised where the paper's algorithm is clear of random, the held-out layouts beside), with its chart."""
    from polyenvs.evaluation.table import environment_section

    lines = ["## Leaderboard", ""]
    if table is None:
        return lines + [
            "No committed results yet (`polyenvs leaderboard --only <name>` evaluates it; see "
            "[the protocol](../guides/leaderboard.md)).",
            "",
        ]
    return lines + [
        "From the committed reference results (`benchmarks/results/`), as `polyenvs leaderboard` computes them "
        "([the protocol](../guides/leaderboard.md)).",
        "",
        *environment_section(env_id, table, chart),
    ]


def citation_section(reference: dict) -> list[str]:
    return [
        "## Citation",
        "",
        "The paper this environment comes from, as `CITATION.cff` cites it (polyenvs' own entry is on "
        "[Citing](../citing.md)):",
        "",
        "```bibtex",
        reference_entry(reference),
        "```",
        "",
    ]


def record(row, cache: Path) -> Path | None:
    """The GIF of the paper's policy on ``row``, recorded by ``polyenvs record`` into ``cache`` (reused if there)."""
    from polyenvs.cli import main

    if paper_policy(row.id) is None:
        return None
    arguments = recording_arguments(row)
    key = re.sub(r"[^A-Za-z0-9]+", "-", " ".join(arguments)).strip("-")
    gif = cache / f"{slug(row.id)}--{key}.gif"
    if gif.exists() and not os.environ.get("POLYENVS_DOCS_RERECORD"):
        return gif
    cache.mkdir(parents=True, exist_ok=True)
    status = main(["record", row.id, "--policy", "paper", *arguments, "--output", str(gif)])
    if status != 0:
        raise RuntimeError(f"polyenvs record {row.id} failed (exit {status})")
    return gif


def key_top(frame: np.ndarray) -> int:
    """The first row of the key under a frame (its grey rule), or the frame's height where it has none."""
    rules = np.flatnonzero((frame == KEY_RULE_GREY).all(axis=(1, 2)))
    return int(rules[-1]) if len(rules) else frame.shape[0]


def robot_spans(video: np.ndarray, colours) -> list[tuple[int, int] | None]:
    """Per frame, the first and last row holding a pixel of one of ``colours`` (None where no robot is drawn)."""
    spans: list[tuple[int, int] | None] = []
    for frame in video:
        robot = np.zeros(frame.shape[:2], dtype=bool)
        for colour in colours:
            robot |= (frame == np.asarray(colour, dtype=frame.dtype)).all(axis=2)
        rows = np.flatnonzero(robot.any(axis=1))
        spans.append((int(rows[0]), int(rows[-1])) if len(rows) else None)
    return spans


def window_tops(spans: list[tuple[int, int] | None], map_height: int, window: int) -> list[int]:
    """The top row of a ``window``-row crop per frame, centred on the frame's robots (where none is drawn, where the
    last frame's were; before any is, where the first are), inside the map."""
    known = [s for s in spans if s is not None]
    centre = (known[0][0] + known[0][1]) / 2 if known else map_height / 2
    tops = []
    for span in spans:
        if span is not None:
            centre = (span[0] + span[1]) / 2
        tops.append(int(np.clip(round(centre - window / 2), 0, map_height - window)))
    return tops


def follow_robots(video: np.ndarray, colours, margin_px: int = FOLLOW_MARGIN_PX) -> np.ndarray:
    """``video`` (frames x height x width x RGB) cut, where its map is taller than wide, to a window that follows
    the robots: as wide as the frame, as tall as the frame is wide or as the robots' widest spread over the episode
    plus ``margin_px`` above and below, whichever is taller; the key under the frame is kept. Every frame keeps
    one size (a GIF's frames share it). Returns ``video`` itself where nothing is cut."""
    map_height, width = key_top(video[0]), video.shape[2]
    spans = robot_spans(video[:, :map_height], colours)
    spread = max((last - first for first, last in filter(None, spans)), default=0)
    window = min(map_height, max(width, spread + 2 * margin_px))
    if window == map_height:
        return video
    tops = window_tops(spans, map_height, window)
    return np.stack(
        [
            np.concatenate([frame[top : top + window], frame[map_height:]])
            for frame, top in zip(video, tops, strict=True)
        ]
    )


def published_recording(row, gif: Path) -> tuple[bytes, bool]:
    """The GIF the page shows, and whether it follows the robots (:func:`follow_robots`); the recording's frame
    durations and looping are kept."""
    colours = ROBOT_COLOURS.get(row.family)
    if colours is None:
        return gif.read_bytes(), False
    import imageio.v3 as iio

    video = iio.imread(gif, index=None)
    followed = follow_robots(video, colours)
    if followed is video:
        return gif.read_bytes(), False
    duration = iio.immeta(gif)["duration"]
    return iio.imwrite("<bytes>", followed, extension=".gif", duration=duration, loop=0), True


def recording_caption(row, followed: bool) -> str:
    command = shlex.join(["polyenvs", "record", row.id, "--policy", "paper", *recording_arguments(row)])
    cut = ", cut to a window that follows the robots" if followed else ""
    return f"*The paper's policy, `{paper_policy(row.id)}`, recorded at build time by `{command}`{cut}.*"


def env_page(row, table: dict | None, media: PageMedia, citation: dict) -> str:
    doc, observation_space, action_space = built_env(row)
    summary, _, body = docstring_markdown(doc).partition("\n\n")  # the first paragraph, however many lines it wraps
    reference = find_reference(citation, PAPERS[row.family][1])
    lines = [f"# `{row.id}`", "", " ".join(summary.split()), ""]
    if media.gif:
        lines += [
            f"![The paper's policy ({paper_policy(row.id)}) on {row.id}]({media.gif})",
            "",
            recording_caption(row, media.followed),
            "",
        ]
    lines += [*facts_table(row, (observation_space, action_space), reference), "", body.strip(), ""]
    lines += [*leaderboard_section(row.id, table, media.chart), *citation_section(reference)]
    return "\n".join(lines)


def gallery(rows, media: dict[str, PageMedia]) -> list[str]:
    """A grid of the rows' recordings, each with its id, linking to its page (the CSS is ``_static/polyenvs.css``)."""
    lines = ["::::{container} polyenvs-gallery"]
    for row in rows:
        gif, page = media[row.id].gif, f"{slug(row.id)}.md"
        if gif:
            lines += ["", ":::{container} polyenvs-card", f"[![{row.id}]({gif})]({page})", "", f"[`{row.id}`]({page})"]
            lines.append(":::")
    return [*lines, "::::", ""]


def index_page(media: dict[str, PageMedia]) -> str:
    lines = [
        "# Environments",
        "",
        "Every row of `polyenvs.registry.REGISTRY`, one page each, generated from the registry and the "
        "environments' docstrings when the documentation is built. Each recording shows the paper's own algorithm.",
        "",
    ]
    for family, title in FAMILY_TITLES.items():
        rows = [r for r in REGISTRY if r.family == family]
        if not rows:
            continue
        lines += [f"## {title}", "", *gallery(rows, media), "| name | what |", "| --- | --- |"]
        lines += [f"| [`{r.id}`]({slug(r.id)}.md) | {r.description} |" for r in rows]
        lines.append("")
    lines += ["```{toctree}", ":hidden:", "", *(slug(r.id) for r in REGISTRY), "```", ""]
    return "\n".join(lines)


def _write_if_changed(path: Path, data: str | bytes) -> None:
    data = data.encode("utf-8") if isinstance(data, str) else data
    if not path.exists() or path.read_bytes() != data:
        path.write_bytes(data)


def leaderboard_chart(env_id: str, root: Path) -> Path:
    """The interval chart of ``env_id`` that ``polyenvs leaderboard --update-reference`` drew beside the committed
    table (it may not exist)."""
    from polyenvs.evaluation.page import plot_path

    return plot_path(root / REFERENCE_TABLE, env_id)


def publish_media(row, has_results: bool, root: Path, out: Path, cache: Path) -> PageMedia:
    """Write the row's recording and its leaderboard chart beside its page; a row with results whose chart is
    missing is a build warning (an error with ``-W``)."""
    from sphinx.util import logging

    gif, followed, chart = record(row, cache), False, leaderboard_chart(row.id, root)
    if gif is not None:
        data, followed = published_recording(row, gif)
        _write_if_changed(out / f"{slug(row.id)}.gif", data)
    if chart.is_file():
        _write_if_changed(out / chart.name, chart.read_bytes())
    elif has_results:
        logging.getLogger(__name__).warning(f"{row.id}: no leaderboard chart at {chart}; the page shows none")
    return PageMedia(f"{slug(row.id)}.gif" if gif else None, followed, chart.name if chart.is_file() else None)


def generate(app) -> None:
    from sphinx.util import logging

    from polyenvs.evaluation.table import leaderboard_tables

    root = Path(app.srcdir).parent
    out = Path(app.srcdir) / "environments"
    out.mkdir(exist_ok=True)
    cache = Path(app.outdir).parent / "recordings"
    citation = load_citation(root / "CITATION.cff")
    tables = leaderboard_tables(reference_documents(root, progress=logging.getLogger(__name__).warning))
    media = {}
    for row in REGISTRY:
        media[row.id] = publish_media(row, row.id in tables, root, out, cache)
        _write_if_changed(out / f"{slug(row.id)}.md", env_page(row, tables.get(row.id), media[row.id], citation))
    _write_if_changed(out / "index.md", index_page(media))
    _write_if_changed(out / "polyenvs.bib", bibtex_file(citation))


def setup(app):
    app.setup_extension("polyenvs_layouts")  # the layouts guide's pictures, drawn like these pages at build time
    app.connect("builder-inited", generate)
    return {"version": "2", "parallel_read_safe": True, "parallel_write_safe": True}
