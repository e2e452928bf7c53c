"""Floor plans made of wall segments, shared by the planar robot families.

A plan is a set of wall segments in centimetres. Beyond the walls themselves it knows a coarse free-space grid:
each cell's distance to the nearest wall and the connected regions of free cells, from which start poses are
drawn and against which coverage is measured.

Conventions every family inherits from here:

- Bad plans fail at construction with a ``ValueError`` naming ``floor_plan``: empty, non-finite, degenerate
  segments, coordinates beyond ``MAX_COORDINATE_CM``, or a plan wider than ``MAX_PLAN_EXTENT_CM``.
- Nothing derived from a plan can take minutes: a free-space grid larger than ``MAX_GRID_CELLS`` is refused with a
  ``ValueError`` naming the grid's cell-size parameter, and every grid is built by compiled code in linear time.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from polyenvs.core.geometry2d import SegmentTable, nearest_wall_points
from polyenvs.core.jit import njit

__all__ = [
    "MAX_COORDINATE_CM",
    "MAX_GRID_CELLS",
    "MAX_PLAN_EXTENT_CM",
    "FloorPlan",
    "FreeSpaceGrid",
    "grid_shape",
    "polygon_walls",
    "rectangle_walls",
]

#: The widest plan accepted (50 m): its 10 cm free-space grid is 250,000 cells.
MAX_PLAN_EXTENT_CM = 5000.0
#: Wall coordinates beyond this (10 km) are refused: float64 positions keep sub-micrometre precision below it.
MAX_COORDINATE_CM = 1e6
#: The largest free-space grid built (about 0.1 s of compiled work).
MAX_GRID_CELLS = 1_000_000


def polygon_walls(*corners: tuple[float, float]) -> list[tuple[float, float, float, float]]:
    """Closed polygon through ``corners`` as wall segments."""
    return [(*corners[i], *corners[(i + 1) % len(corners)]) for i in range(len(corners))]


def rectangle_walls(x0: float, y0: float, x1: float, y1: float) -> list[tuple[float, float, float, float]]:
    return polygon_walls((x0, y0), (x1, y0), (x1, y1), (x0, y1))


@dataclass(frozen=True)
class FreeSpaceGrid:
    """A coarse raster of a plan: cell centres, their clearance to walls, and the region they belong to.

    Attributes:
        origin: world coordinates (cm) of cell (0, 0)'s lower-left corner.
        cell_cm: cell size.
        clearance: ``(H, W)`` distance from each cell centre to the nearest wall.
        region: ``(H, W)`` region label of each free cell, -1 for cells touching a wall.
        main_region: the label of the largest region enclosed by walls (or the largest region if none is enclosed).
    """

    origin: np.ndarray
    cell_cm: float
    clearance: np.ndarray
    region: np.ndarray
    main_region: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.clearance.shape

    def centres(self) -> np.ndarray:
        h, w = self.shape
        ys, xs = np.mgrid[0:h, 0:w]
        return self.origin + (np.stack([xs, ys], axis=-1) + 0.5) * self.cell_cm

    def cell_index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of points, clipped to the grid."""
        idx = np.floor((points - self.origin) / self.cell_cm).astype(np.int64)
        h, w = self.shape
        return np.clip(idx[..., 1], 0, h - 1), np.clip(idx[..., 0], 0, w - 1)


@njit(cache=True)
def _label_regions(free):
    """4-connected component labels of ``free`` cells, -1 elsewhere; a component's label is its lowest flat index.

    A flood fill from each unlabelled cell in raster order: linear in the number of cells.
    """
    h, w = free.shape
    labels = np.full((h, w), -1, dtype=np.int64)
    stack = np.empty(h * w, dtype=np.int64)
    for start in range(h * w):
        r0, c0 = start // w, start % w
        if not free[r0, c0] or labels[r0, c0] >= 0:
            continue
        labels[r0, c0] = start
        top = 0
        stack[top] = start
        top += 1
        while top > 0:
            top -= 1
            cell = stack[top]
            r, c = cell // w, cell % w
            for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < h and 0 <= cc < w and free[rr, cc] and labels[rr, cc] < 0:
                    labels[rr, cc] = start
                    stack[top] = rr * w + cc
                    top += 1
    return labels


def grid_shape(bounds, cell_cm: float) -> tuple[np.ndarray, tuple[int, int]]:
    """Origin and (rows, cols) of the free-space grid over ``bounds`` (xmin, ymin, xmax, ymax), 2 cells of margin."""
    xmin, ymin, xmax, ymax = bounds
    margin = 2 * cell_cm
    origin = np.array([xmin - margin, ymin - margin])
    w = int(np.ceil((xmax - xmin + 2 * margin) / cell_cm))
    h = int(np.ceil((ymax - ymin + 2 * margin) / cell_cm))
    return origin, (h, w)


@dataclass(frozen=True, eq=False)
class FloorPlan:
    """Walls as segments ``(x1, y1, x2, y2)`` in centimetres.

    Args:
        segments: sequence of 4-tuples. Must be non-empty, finite and without zero-length segments.
        name: a label for reports and rendering.
    """

    segments: np.ndarray
    name: str = "custom"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        try:
            seg = np.array(self.segments, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError("floor_plan must be a plan name or a list of (x1, y1, x2, y2) segments in cm") from None
        if seg.size == 0:
            raise ValueError("floor_plan has no wall segments")
        if seg.ndim != 2 or seg.shape[1] != 4:
            raise ValueError(f"floor_plan segments must have shape (S, 4), got {seg.shape}")
        if not np.isfinite(seg).all():
            raise ValueError("floor_plan segments must be finite numbers")
        if np.abs(seg).max() > MAX_COORDINATE_CM:
            raise ValueError(f"floor_plan coordinates must lie within ±{MAX_COORDINATE_CM:g} cm")
        extent = max(np.ptp(seg[:, [0, 2]]), np.ptp(seg[:, [1, 3]]))
        if extent > MAX_PLAN_EXTENT_CM:
            raise ValueError(f"floor_plan spans {extent:g} cm; at most {MAX_PLAN_EXTENT_CM:g} cm (50 m) is supported")
        lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        if (lengths < 1e-6).any():
            bad = int(np.flatnonzero(lengths < 1e-6)[0])
            raise ValueError(f"floor_plan segment {bad} {tuple(seg[bad])} is degenerate (zero length)")
        seg.setflags(write=False)
        object.__setattr__(self, "segments", seg)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the walls."""
        pts = self.segments.reshape(-1, 2)
        return (*pts.min(axis=0), *pts.max(axis=0))

    @functools.cached_property
    def table(self) -> SegmentTable:
        return SegmentTable(self.segments)

    def clearance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each point ``(..., 2)`` to the nearest wall."""
        pts = np.asarray(points, dtype=np.float64)
        flat = pts.reshape(1, -1, 2)
        return nearest_wall_points(self.table, flat)[0].reshape(pts.shape[:-1])

    def check_grid(self, cell_cm: float, name: str = "cell_cm") -> None:
        """Raise ``ValueError`` naming ``name`` if the grid at ``cell_cm`` would exceed ``MAX_GRID_CELLS``."""
        _, (h, w) = grid_shape(self.bounds, cell_cm)
        if h * w > MAX_GRID_CELLS:
            raise ValueError(
                f"{name}={cell_cm:g} makes a {w} x {h} grid over this floor plan ({h * w:,} cells; at most "
                f"{MAX_GRID_CELLS:,}): use larger cells"
            )

    def grid(self, cell_cm: float = 10.0) -> FreeSpaceGrid:
        """The plan's free-space grid (cached per cell size)."""
        if cell_cm not in self._cache:
            self.check_grid(cell_cm)
            self._cache[cell_cm] = self._make_grid(cell_cm)
        return self._cache[cell_cm]

    def _make_grid(self, cell_cm: float) -> FreeSpaceGrid:
        origin, (h, w) = grid_shape(self.bounds, cell_cm)
        ys, xs = np.mgrid[0:h, 0:w]
        centres = origin + (np.stack([xs, ys], axis=-1) + 0.5) * cell_cm
        clearance = self.clearance(centres)
        free = clearance > cell_cm * 0.75  # a wall passes within the cell's reach: not free
        region = _label_regions(free)
        border = np.unique(np.concatenate([region[0], region[-1], region[:, 0], region[:, -1]]))
        labels, counts = np.unique(region[region >= 0], return_counts=True)
        enclosed = ~np.isin(labels, border)
        candidates = (labels[enclosed], counts[enclosed]) if enclosed.any() else (labels, counts)
        main = int(candidates[0][np.argmax(candidates[1])]) if candidates[0].size else -1
        return FreeSpaceGrid(origin, float(cell_cm), clearance, region, main)

    def has_room(self, min_clearance: float, cell_cm: float = 10.0) -> bool:
        """Whether the main region has points at least ``min_clearance`` from every wall (a start can be drawn)."""
        g = self.grid(cell_cm)
        return g.main_region >= 0 and bool(
            ((g.region == g.main_region) & (g.clearance >= min_clearance + cell_cm)).any()
        )

    def in_main_region(self, point, cell_cm: float = 10.0) -> bool:
        """Whether ``point`` lies in the plan's main free region (inside the room, not outside its walls)."""
        g = self.grid(cell_cm)
        row, col = g.cell_index(np.asarray(point, dtype=np.float64))
        # Cells hugging a wall are not labelled; a point there belongs to the region of its neighbours.
        block = g.region[max(row - 1, 0) : row + 2, max(col - 1, 0) : col + 2]
        return bool((block == g.main_region).any())

    def sample_start(self, rng: np.random.Generator, min_clearance: float, cell_cm: float = 10.0) -> np.ndarray:
        """A uniformly drawn point of the main region at least ``min_clearance`` from every wall: one cell among
        the eligible ones, then a uniform point inside it."""
        key = ("eligible", float(min_clearance), float(cell_cm))
        if key not in self._cache:
            g = self.grid(cell_cm)
            eligible = np.flatnonzero(((g.region == g.main_region) & (g.clearance >= min_clearance + cell_cm)).ravel())
            self._cache[key] = (eligible, g.shape[1], g.origin, g.cell_cm)
        eligible, width, origin, cell = self._cache[key]
        if eligible.size == 0:
            raise ValueError(
                f"floor_plan {self.name!r} has no free space at least {min_clearance:.1f} cm from every wall"
            )
        # One call for the three uniforms: the cell (a uniform index; a float's 53 bits leave no visible bias)
        # and the point inside it.
        pick, u, v = rng.random(3).tolist()
        row, col = divmod(int(eligible[int(pick * eligible.size)]), width)
        return np.array([origin[0] + (col + u) * cell, origin[1] + (row + v) * cell])
