"""Sphinx extension: the ``layouts-figure`` directive of the layouts guide (``guides/layouts.md``).

````md
```{layouts-figure} polyenvs/BuckybotWallFollow-v0
```
````

draws, when the page is read, a grid of the environment's own ``rgb_array`` frames at the reset of seeds 0-3 with
``layouts="train"`` and with ``layouts="test"``, and writes under it the kinds of feature each pictured layout holds
and the share of 100 seeded episodes of each side that hold each kind (its family's ``LAYOUT_KINDS``, found by its
``episode_kinds``). The picture is written to ``environments/`` (git-ignored, generated like the environment pages by
``polyenvs_pages``), so nothing drawn is committed; a page that holds the directive is read again at every build, so
its pictures follow the code.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
from docutils import nodes
from docutils.statemachine import StringList
from polyenvs_pages import key_top
from sphinx.util.docutils import SphinxDirective

from polyenvs.buckybot import floor_plans
from polyenvs.bumper import maps
from polyenvs.registry import entry, slug
from polyenvs.swarm import layouts as swarm_layouts

#: Where each family declares its kinds (``LAYOUT_KINDS``) and finds them in an episode (``episode_kinds``).
KIND_MODULES = {"buckybot": floor_plans, "bumper": maps, "swarm": swarm_layouts}
SIDES = ("train", "test")
PICTURED_SEEDS = 4
COUNTED_SEEDS = 100
GUTTER_PX = 12
WHITE = 255


def episode_frames_and_kinds(env_id: str, layouts: str) -> tuple[list[np.ndarray], list[frozenset[str]], Counter]:
    """The frames of the first :data:`PICTURED_SEEDS` resets of ``env_id`` with ``layouts``, their kinds, and how
    many of :data:`COUNTED_SEEDS` resets hold each kind."""
    from polyenvs.evaluation.rollout import make_env

    finder = KIND_MODULES[entry(env_id).family].episode_kinds
    env = make_env(env_id, {"layouts": layouts}, render_mode="rgb_array")
    frames, pictured, counted = [], [], Counter()
    try:
        core = env.unwrapped if hasattr(env, "unwrapped") else env
        for seed in range(COUNTED_SEEDS):
            env.reset(seed=seed)
            kinds = finder(core)
            counted.update(kinds)
            if seed < PICTURED_SEEDS:
                frames.append(np.asarray(env.render()))
                pictured.append(kinds)
    finally:
        env.close()
    return frames, pictured, counted


def grid(frames: dict[str, list[np.ndarray]]) -> np.ndarray:
    """The frames' maps in a grid on white, a row per side (one row for frames taller than wide, the training side
    first), and the key under the first frame once, below."""
    first = frames[SIDES[0]][0]
    top = key_top(first)
    maps_only = [[frame[:top] for frame in frames[side]] for side in SIDES]
    gutter = np.full((top, GUTTER_PX, 3), WHITE, dtype=np.uint8)

    def row(tiles):
        return np.concatenate([part for tile in tiles for part in (tile, gutter)][:-1], axis=1)

    if top > first.shape[1]:  # tall frames (a corridor): all in one row
        rows = [row(maps_only[0] + maps_only[1])]
    else:
        rows = [row(tiles) for tiles in maps_only]
    width = rows[0].shape[1]
    between = np.full((GUTTER_PX, width, 3), WHITE, dtype=np.uint8)
    key = np.full((first.shape[0] - top, width, 3), WHITE, dtype=np.uint8)
    key[:, : first.shape[1]] = first[top:]
    return np.concatenate([part for r in rows for part in (r, between)] + [key], axis=0)


def figure_markdown(env_id: str, image: str, pictured: dict, counted: dict, tall: bool) -> list[str]:
    """The picture, its caption, the pictured layouts' kinds and each kind's share of each side's episodes."""
    where = "left four" if tall else "top row"
    other = "right four" if tall else "bottom row"
    lines = [
        f"![Training and held-out layouts of {env_id}]({image})",
        "",
        f'*`{env_id}` at the reset of seeds 0-{PICTURED_SEEDS - 1}: `layouts="train"` ({where}), `layouts="test"` '
        f"({other}); its own `rgb_array` frames, drawn when this page was built.*",
        "",
        "| seed | " + " | ".join(f'`layouts="{side}"`' for side in SIDES) + " |",
        "| --- | --- | --- |",
    ]
    for seed in range(PICTURED_SEEDS):
        cells = [", ".join(sorted(pictured[side][seed])) or "-" for side in SIDES]
        lines.append(f"| {seed} | " + " | ".join(cells) + " |")
    lines += ["", f"| kind | what it is | share of {COUNTED_SEEDS} train episodes | of {COUNTED_SEEDS} test episodes |"]
    lines.append("| --- | --- | --- | --- |")
    for kind in KIND_MODULES[entry(env_id).family].LAYOUT_KINDS:
        shares = [f"{100 * counted[side][kind.name] / COUNTED_SEEDS:.0f} %" for side in SIDES]
        lines.append(f"| {kind.name} | {kind.meaning} | " + " | ".join(shares) + " |")
    return [*lines, ""]


class LayoutsFigure(SphinxDirective):
    """``{layouts-figure} ENV_ID``: the grid, its caption and the kinds tables (see the module's docstring)."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        import imageio.v3 as iio

        env_id = self.arguments[0]
        self.env.note_reread()  # drawn from the code, not from the page: redrawn at every build
        frames, pictured, counted = {}, {}, {}
        for side in SIDES:
            frames[side], pictured[side], counted[side] = episode_frames_and_kinds(env_id, side)
        out = Path(self.env.srcdir) / "environments"
        out.mkdir(exist_ok=True)
        picture = out / f"layouts-{slug(env_id)}.png"
        picture.write_bytes(iio.imwrite("<bytes>", grid(frames), extension=".png"))
        image = os.path.relpath(picture, Path(self.env.doc2path(self.env.docname)).parent)
        tall = key_top(frames[SIDES[0]][0]) > frames[SIDES[0]][0].shape[1]
        container = nodes.container()
        markdown = figure_markdown(env_id, image, pictured, counted, tall)
        self.state.nested_parse(StringList(markdown), self.content_offset, container)
        return container.children


def setup(app):
    app.add_directive("layouts-figure", LayoutsFigure)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
