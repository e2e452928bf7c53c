"""Sphinx extension: one page per registry row, written into the source tree when the build starts.

Each page is made from what the code already holds, so no text is copied into ``docs/``: the row of
:data:`polyenvs.registry.REGISTRY` (its kind, episode limit, baselines, extra and, once rows carry one, its task
score), the environment class's Gymnasium-style docstring (its ``##`` sections are Markdown already), the
leaderboard section written by :func:`polyenvs.leaderboard.environment_section` from the committed result files in
``benchmarks/results/``, and a GIF of the paper's policy recorded by ``polyenvs record`` at build time.

Recordings are cached in ``<build>/recordings/`` under a name that includes their recording arguments, so a
second build reuses them; delete the folder (or set ``POLYENVS_DOCS_RERECORD=1``) to record them again. The
generated pages live in ``docs/environments/`` (git-ignored) and are rewritten only when their text changes, so an
incremental build rebuilds only what changed.
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import re
import shlex
import shutil
from pathlib import Path

from polyenvs.registry import REGISTRY, EnvEntry, import_attribute, slug

#: The paper each family comes from: (its page under papers/, a short citation).
PAPERS = {
    "buckybot": (
        "buckybot",
        '"Buckybot: preliminary control and mapping algorithms"',
    ),
    "beast": ("beasts", 'Pai, Barman and Ralph, "Platonic beasts: spherically symmetric multilimbed robots"'),
    "swarm": ("swarm", 'Hettiarachchi and Spears, "Physicomimetics for mobile robot obstacle avoidance"'),
    "bumper": ("bumper", 'Dye, "Mapping with only a bumper"'),
}
FAMILY_TITLES = {
    "buckybot": "Buckybot",
    "beast": "Platonic beasts (MuJoCo)",
    "bumper": "The bump-only cart",
    "swarm": "AP-lite and physicomimetics swarms",
}

#: ``polyenvs record`` arguments per family: a few seconds of the paper's policy in small frames, so the 17
#: recordings take about two minutes on two cores.
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


def recording_arguments(row) -> list[str]:
    return RECORDING_BY_ID.get(row.id, RECORDING[row.family])


_ROLE = re.compile(r":(class|func|mod|meth|attr|data|obj|exc):`([^`]+)`")


def docstring_markdown(text: str) -> str:
    """A Gymnasium-style docstring as MyST: dedented, reStructuredText roles written as MyST roles."""
    return _ROLE.sub(r"{py:\1}`\2`", inspect.cleandoc(text))


def env_docstring(row) -> str:
    if isinstance(row, EnvEntry):
        return import_attribute(row.entry_point).__doc__ or ""
    env = importlib.import_module(row.id).parallel_env(max_cycles=row.max_cycles, **row.kwargs)
    try:
        return inspect.getdoc(type(env)) or ""
    finally:
        env.close()


def _score_text(score) -> str:
    """The row's task score (:class:`polyenvs.registry.Score`): its fields that are set."""
    fields = {name: getattr(score, name) for name in score.__dataclass_fields__}
    return ", ".join(f"{name} `{value}`" for name, value in fields.items() if value is not None)


def facts_table(row) -> list[str]:
    family = row.family
    paper_page, citation = PAPERS.get(family, (None, "-"))
    names = [f"`{b.name}`" + (" (the paper's)" if b.name == row.paper else "") for b in row.baselines]
    if isinstance(row, EnvEntry):
        kind = "Gymnasium id"
        make = f'`gym.make("{row.id}")`'
        limit = f"{row.max_episode_steps} steps (`max_episode_steps`)"
        if row.vector_entry_point:
            make += f', native vector env: `gym.make_vec("{row.id}", num_envs=N)`'
    else:
        kind = "PettingZoo parallel environment"
        make = f"`{row.id}.parallel_env()` (AEC: `{row.id}.env()`)"
        limit = f"{row.max_cycles} cycles (`max_cycles`)"
    lines = [
        "| | |",
        "| --- | --- |",
        f"| kind | {kind} |",
        f"| make | {make} |",
        f"| episode limit | {limit} |",
        f'| install | `pip install "polyenvs[{row.extra}]"` |' if row.extra else "| install | `pip install polyenvs` |",
        f"| hand baselines | {', '.join(names) or '-'} |",
        f"| task score | {_score_text(row.score)} |",
        f"| paper | [{citation}](../papers/{paper_page}.md) |" if paper_page else "| paper | - |",
    ]
    estimators = getattr(row, "estimators", ())
    if estimators:
        lines.append(
            f"| estimators | {', '.join(f'`{e.name}`' for e in estimators)} ([the benchmark](../guides/localization.md)) |"
        )
    return lines


def stored_documents(results_dir: Path) -> list[dict]:
    """Every usable result document in ``results_dir``, checked by :func:`polyenvs.leaderboard.load_result`."""
    from polyenvs.leaderboard import load_result

    documents = []
    for path in sorted(results_dir.glob("*.json")):
        try:
            head = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(head, dict) and "env_id" in head and "policy" in head:
            doc, _ = load_result(path, head["env_id"], head["policy"])
            if doc is not None:
                documents.append(doc)
    return documents


def leaderboard_section(env_id: str, table: dict | None) -> list[str]:
    """The environment's part of the leaderboard, as ``polyenvs leaderboard`` writes it (ranked by the task score,
    normalised where the paper's algorithm is clear of random, the held-out layouts beside)."""
    from polyenvs.leaderboard import environment_section

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
        *environment_section(env_id, table),
    ]


def record(row, cache: Path) -> Path | None:
    """The GIF of the paper's policy on ``row``, recorded by ``polyenvs record`` into ``cache`` (reused if there)."""
    from polyenvs.cli import main

    if row.paper is None:
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


def env_page(row, table: dict | None, gif_name: str | None) -> str:
    doc = docstring_markdown(env_docstring(row))
    summary, _, body = doc.partition("\n\n")  # the first paragraph, however many lines it wraps over
    lines = [f"# `{row.id}`", "", " ".join(summary.split()), ""]
    if gif_name:
        lines += [
            f"![The paper's policy ({row.paper}) on {row.id}]({gif_name})",
            "",
            f"*The paper's policy, `{row.paper}`, recorded at build time by "
            f"`{shlex.join(['polyenvs', 'record', row.id, '--policy', 'paper', *recording_arguments(row)])}`.*",
            "",
        ]
    lines += [*facts_table(row), "", body.strip(), "", *leaderboard_section(row.id, table)]
    return "\n".join(lines)


def index_page() -> str:
    lines = [
        "# Environments",
        "",
        "Every row of `polyenvs.registry.REGISTRY`, one page each, generated from the registry and the "
        "environments' docstrings when the documentation is built.",
        "",
    ]
    for family, title in FAMILY_TITLES.items():
        rows = [r for r in REGISTRY if r.family == family]
        if not rows:
            continue
        lines += [f"## {title}", "", "| name | what |", "| --- | --- |"]
        lines += [f"| [`{r.id}`]({slug(r.id)}.md) | {r.description} |" for r in rows]
        lines.append("")
    lines += ["```{toctree}", ":hidden:", "", *(slug(r.id) for r in REGISTRY), "```", ""]
    return "\n".join(lines)


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def generate(app) -> None:
    from polyenvs.leaderboard import leaderboard_tables

    root = Path(app.srcdir).parent
    out = Path(app.srcdir) / "environments"
    out.mkdir(exist_ok=True)
    cache = Path(app.outdir).parent / "recordings"
    tables = leaderboard_tables(stored_documents(root / "benchmarks" / "results"))
    for row in REGISTRY:
        gif = record(row, cache)
        gif_name = None
        if gif is not None:
            gif_name = f"{slug(row.id)}.gif"
            if not (out / gif_name).exists() or (out / gif_name).read_bytes() != gif.read_bytes():
                shutil.copyfile(gif, out / gif_name)
        _write_if_changed(out / f"{slug(row.id)}.md", env_page(row, tables.get(row.id), gif_name))
    _write_if_changed(out / "index.md", index_page())


def setup(app):
    app.connect("builder-inited", generate)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
