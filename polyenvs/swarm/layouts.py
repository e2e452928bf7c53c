"""Geometry the tasks share: boxes of walls, start blocks, the hexagonal lattice and seeded obstacle fields."""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core import libm
from polyenvs.core.layouts import check_layouts
from polyenvs.core.validation import check_int

__all__ = ["box_walls", "hex_lattice", "lattice_pairs", "layout_obstacle_slots", "random_obstacles", "start_block"]


def box_walls(xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
    """The four walls of an axis-aligned rectangle, ``(4, 4)``."""
    return np.array(
        [[xmin, ymin, xmax, ymin], [xmax, ymin, xmax, ymax], [xmax, ymax, xmin, ymax], [xmin, ymax, xmin, ymin]]
    )


def start_block(n: int, columns: int, spacing: float) -> np.ndarray:
    """``n`` slots ``(n, 2)`` on a square grid of ``columns`` columns, in rows going away from the origin:
    column offsets ``0, spacing, ...`` along x and row offsets ``0, spacing, ...`` along y."""
    index = np.arange(n)
    return np.column_stack([(index % columns) * spacing, (index // columns) * spacing]).astype(np.float64)


def hex_lattice(n: int, spacing: float) -> np.ndarray:
    """The ``n`` points of a hexagonal lattice of side ``spacing`` nearest the origin ``(n, 2)``, the origin (the
    leader) first; for 7, a hexagon around the leader. Ties are broken by angle, so the result is fixed."""
    rings = math.ceil(math.sqrt(n)) + 1
    i, j = np.meshgrid(np.arange(-rings, rings + 1), np.arange(-rings, rings + 1), indexing="ij")
    points = np.column_stack([(i + 0.5 * j).ravel(), (j * math.sqrt(3) / 2).ravel()]) * spacing
    radius = np.round(np.hypot(points[:, 0], points[:, 1]) / spacing, 6)
    angle = np.round(np.mod(libm.arctan2(points[:, 1], points[:, 0]), 2 * np.pi), 6)
    order = np.lexsort((angle, radius))
    return points[order[:n]]


def lattice_pairs(points: np.ndarray, spacing: float) -> np.ndarray:
    """Index pairs ``(P, 2)`` of lattice points one ``spacing`` apart (the formation's neighbours)."""
    d = np.hypot(*(points[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
    i, j = np.nonzero(np.triu(np.abs(d - spacing) < 1e-6 * spacing, 1))
    return np.column_stack([i, j]).astype(np.int64)


def random_obstacles(rng: np.random.Generator, count: int, region, radius_range, gap: float, keep_out) -> np.ndarray:
    """``count`` discs ``(count, 3)`` with centres uniform in ``region`` = (xmin, ymin, xmax, ymax) and radii
    uniform in ``radius_range``, at least ``gap`` apart (rim to rim) and clear of each ``keep_out`` disc
    (x, y, r) by ``gap``. Rejection sampling; a region too crowded for ``count`` discs places fewer."""
    xmin, ymin, xmax, ymax = region
    discs = [tuple(d) for d in keep_out]
    placed: list[tuple[float, float, float]] = []
    for _ in range(200 * max(count, 1)):
        if len(placed) == count:
            break
        x, y = xmin + (xmax - xmin) * rng.random(), ymin + (ymax - ymin) * rng.random()
        r = radius_range[0] + (radius_range[1] - radius_range[0]) * rng.random()
        if all(math.hypot(x - a, y - b) >= r + c + gap for a, b, c in discs + placed):
            placed.append((x, y, r))
    return np.array(placed, dtype=np.float64).reshape(-1, 3)


def layout_obstacle_slots(n_obstacles, layouts, default: int, most: int) -> int:
    """The obstacle slots of a field: ``n_obstacles`` (checked), or with ``layouts="train"`` or ``"test"``, which
    draw their own count, the most they draw (a ``n_obstacles`` other than ``default`` is refused, not ignored)."""
    n_obstacles = check_int("n_obstacles", n_obstacles, 0, 200)
    if check_layouts(layouts) == "default":
        return n_obstacles
    if n_obstacles != default:
        raise ValueError(
            f"layouts={layouts!r} draws its own obstacles: leave n_obstacles at its default ({default}), or use "
            f"layouts='default' with n_obstacles={n_obstacles}"
        )
    return most
