"""Top-down frames of a bumper-cart episode: the map, the touched wall cells, the true and dead-reckoned paths,
the bump points and the cart (its body and, in front, the bumper).

Drawn with the numpy rasterizer (:mod:`polyenvs.core.raster`), so ``rgb_array`` needs nothing beyond numpy;
``human`` mode shows the frames in a pygame window (``pip install "polyenvs[render]"``).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.bumper import cart as C
from polyenvs.core.raster import DEAD_RECKONED_PATH, FRAME_WIDTH_PX, TRUE_PATH, Canvas, with_legend
from polyenvs.core.window import TopDownRenderer

__all__ = ["BumperRenderer", "FRAME_WIDTH_PX", "draw_belief", "draw_touched_cells"]

TOUCHED = (40, 170, 60)
BUMP = (230, 120, 0)
BODY = (250, 190, 60)
BUMPER = (120, 60, 0)
PARTICLE = (150, 150, 150)
ESTIMATE = (60, 90, 220)
#: At most this many particles are drawn (evenly strided): more only darken the frame.
PARTICLES_DRAWN = 600


def body_outline(pose, model) -> np.ndarray:
    """The cart's body rectangle at ``pose`` (x, y, heading rad): front right, front left, rear left, rear right."""
    x, y, h = pose
    c, s = math.cos(h), math.sin(h)
    half = model.bumper_width_cm / 2
    local = np.array([(model.bumper_offset_cm, -half), (model.bumper_offset_cm, half), (-model.rear_cm, half),
                      (-model.rear_cm, -half)])  # fmt: skip
    return np.stack([x + local[:, 0] * c - local[:, 1] * s, y + local[:, 0] * s + local[:, 1] * c], axis=-1)


def draw_touched_cells(canvas: Canvas, env) -> None:
    """Row 0's touched wall cells (:class:`~polyenvs.bumper.env.BumperCartExploreEnv`'s layer)."""
    seg = env.world.segments
    # Touched cells: each segment's cells are equal parts of it.
    touched = np.flatnonzero(env._touched[0])
    if len(touched):
        owner = np.searchsorted(env._cell_first, touched, side="right") - 1
        k = (touched - env._cell_first[owner])[:, None]
        n = env._cell_count[owner][:, None]
        start, vector = seg[owner, :2], seg[owner, 2:] - seg[owner, :2]
        canvas.lines(start + vector * k / n, start + vector * (k + 1) / n, TOUCHED, width_px=5.0)


def draw_belief(canvas: Canvas, particles: np.ndarray, estimate) -> None:
    """Row 0's particles (grey) and the localizer's estimate with its heading (blue): the localization task's layer."""
    stride = max(1, len(particles) // PARTICLES_DRAWN)
    canvas.points(particles[::stride, :2], PARTICLE, radius_px=1.5)
    x, y, h = estimate
    tip = np.array([[x + 8.0 * math.cos(h), y + 8.0 * math.sin(h)]])
    canvas.lines(np.array([[x, y]]), tip, ESTIMATE, width_px=2.0)
    canvas.points(np.array([[x, y]]), ESTIMATE, radius_px=4.0)


class BumperRenderer(TopDownRenderer):
    """Renders row 0 of a :class:`~polyenvs.bumper.env.BumperCartEnv` (the map, the task's layer, the paths, the
    cart); every frame covers the map's bounds, so one instance makes frames of one size."""

    caption = "polyenvs bumper cart"

    def __init__(self, render_mode: str, fps: int, bounds, window_scale: float = 1.0):
        x0, y0, x1, y1 = bounds
        pad = 0.05 * max(x1 - x0, y1 - y0)
        super().__init__(render_mode, fps, (x0 - pad, y0 - pad, x1 + pad, y1 + pad), window_scale)

    def frame(self, env) -> np.ndarray:
        canvas = self.canvas_with_walls(env.world.segments)
        env.draw_task(canvas)
        true_path, dead_reckoned, bumps = (np.array(p, dtype=np.float64).reshape(-1, 2) for p in env._paths)
        if len(dead_reckoned) > 1:
            canvas.polyline(dead_reckoned, DEAD_RECKONED_PATH, width_px=1.5)
        if len(true_path) > 1:
            canvas.polyline(true_path, TRUE_PATH, width_px=1.5)
        if len(bumps):
            canvas.points(bumps, BUMP, radius_px=3.0)
        state = env.state[0]
        outline = body_outline((state[C.X], state[C.Y], state[C.HEADING]), env.model)
        canvas.polygon(outline, BODY, outline=BUMPER)
        canvas.lines(outline[0:1], outline[1:2], BUMPER, width_px=3.0)
        key = [
            ("true path", TRUE_PATH),
            ("dead reckoned", DEAD_RECKONED_PATH),
            ("bump", BUMP),
            ("wall touched", TOUCHED),
        ]
        return with_legend(canvas.image, key)
