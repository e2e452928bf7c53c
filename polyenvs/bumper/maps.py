"""Polygonal maps for the bumper cart: an outer wall polygon and obstacle polygons inside it.

A map is a list of closed polygons in centimetres: the first is the room's outline, the others are obstacles
(interior walls, boxes) strictly inside it and apart from each other. Free space is inside the outline and outside
every obstacle, so a point-in-polygon crossing count over all the segments at once decides it (odd = free).

Built-in maps (``MAPS``):

| name | what |
| --- | --- |
| ``paper`` | the paper's arena: a 120 x 90 cm rectangle with its north-west corner cut at 45° (legs of 40 cm); sizes *ours*, from the feasibility study (the paper gives none) |
| ``rectangle`` | the same rectangle without the cut: symmetric, so a bump-only localizer cannot tell its ends apart |
| ``l_room`` | an L-shaped room, 160 cm wide with a 80 x 80 cm notch |
| ``obstacles`` | the paper's arena with two boxes in it |
| ``maze`` | a 200 x 200 cm maze of free-standing 2 cm walls with gaps the cart fits through |

Held-out layouts (``layouts=`` of the cart ids, :data:`LAYOUT_SPLIT`): random rooms with boxes
(:func:`random_room_map`), a rectangle 70-120 cm deep, one corner cut at 45° half the time, and up to two boxes;
"train" rooms are 90-140 cm wide, "test" rooms 150-200 cm. The default map (``paper``) is not a test room. Both sides
draw the same kinds of feature (:data:`LAYOUT_KINDS`, found by :func:`map_kinds`): a 45° wall, boxes.

A user map is a sequence of polygons, each a sequence of ``(x, y)`` vertices (or a single polygon). Bad maps raise
``ValueError`` naming ``map``: fewer than 3 vertices, non-finite or huge coordinates, edges under ``MIN_EDGE_CM``,
self-intersecting or crossing polygons, obstacles outside the outline, more than ``MAX_SEGMENTS`` edges, or no room
for the cart.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from polyenvs.core.geometry2d import pack_segments
from polyenvs.core.jit import njit
from polyenvs.core.layouts import DIAGONAL_WALL, LayoutKind, LayoutSplit, SplitParameter, wall_direction_kinds

__all__ = [
    "LAYOUT_KINDS",
    "LAYOUT_MAX_SEGMENTS",
    "LAYOUT_ROOM_BOUNDS",
    "LAYOUT_SPLIT",
    "MAPS",
    "MAX_EXTENT_CM",
    "MAX_SEGMENTS",
    "MIN_EDGE_CM",
    "BumperMap",
    "episode_kinds",
    "free_at",
    "layout_map",
    "make_map",
    "map_kinds",
    "random_room_map",
]

#: The widest map accepted (20 m); the cart is 12 cm long.
MAX_EXTENT_CM = 2000.0
#: Edges of all polygons together: every cycle solves the cart against each of them.
MAX_SEGMENTS = 256
#: Shorter edges are refused (a degenerate polygon, or a typing slip).
MIN_EDGE_CM = 0.5


def _box(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _maze():
    outer = _box(0.0, 0.0, 200.0, 200.0)
    # Free-standing walls (2 cm thick) leaving gaps of 24 cm or more; no wall touches another.
    walls = [
        _box(50.0, 24.0, 52.0, 150.0),
        _box(100.0, 50.0, 102.0, 176.0),
        _box(150.0, 24.0, 152.0, 150.0),
        _box(24.0, 174.0, 76.0, 176.0),
        _box(126.0, 98.0, 148.0, 100.0),
    ]
    return [outer, *walls]


#: name -> list of polygons (outline first).
MAPS: dict[str, list[list[tuple[float, float]]]] = {
    "paper": [[(0.0, 0.0), (120.0, 0.0), (120.0, 90.0), (40.0, 90.0), (0.0, 50.0)]],
    "rectangle": [_box(0.0, 0.0, 120.0, 90.0)],
    "l_room": [[(0.0, 0.0), (160.0, 0.0), (160.0, 80.0), (80.0, 80.0), (80.0, 160.0), (0.0, 160.0)]],
    "obstacles": [
        [(0.0, 0.0), (120.0, 0.0), (120.0, 90.0), (40.0, 90.0), (0.0, 50.0)],
        _box(30.0, 20.0, 45.0, 32.0),
        _box(80.0, 50.0, 92.0, 70.0),
    ],
    "maze": _maze(),
}


@njit(cache=True)
def free_at(x, y, walls):
    """Whether ``(x, y)`` is in the free space of packed ``walls`` (S, 6): an odd number of edges cross the ray to
    +x (the outline once, each obstacle an even number of times unless the point is inside it)."""
    inside = False
    for k in range(walls.shape[0]):
        if walls[k, 5] == 0.0:
            continue
        y0, y1 = walls[k, 1], walls[k, 1] + walls[k, 3]
        if (y0 > y) != (y1 > y):
            x_cross = walls[k, 0] + (y - y0) / walls[k, 3] * walls[k, 2]
            if x < x_cross:
                inside = not inside
    return inside


@njit(cache=True)
def _clearance(x, y, walls):
    best = math.inf
    for k in range(walls.shape[0]):
        if walls[k, 5] == 0.0:
            continue
        along = ((x - walls[k, 0]) * walls[k, 2] + (y - walls[k, 1]) * walls[k, 3]) * walls[k, 4]
        along = min(max(along, 0.0), 1.0)
        dx, dy = x - walls[k, 0] - along * walls[k, 2], y - walls[k, 1] - along * walls[k, 3]
        best = min(best, dx * dx + dy * dy)
    return math.sqrt(best)


@njit(cache=True)
def _free_clearance(points, walls, out):
    for i in range(points.shape[0]):
        out[i] = _point_clearance(points[i, 0], points[i, 1], walls)


@njit(cache=True)
def _point_clearance(x, y, walls) -> float:
    """:meth:`BumperMap.clearance` of one point, without building arrays (a reset's rejection sampling)."""
    return _clearance(x, y, walls) if free_at(x, y, walls) else -_clearance(x, y, walls)


def _free_side(polygon: np.ndarray, outline: bool) -> float:
    """+1 if free space lies left of the polygon's edges (inside a counter-clockwise outline, outside a clockwise
    obstacle), else -1."""
    x, y = polygon[:, 0], polygon[:, 1]
    counter_clockwise = float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) > 0.0
    return 1.0 if counter_clockwise == outline else -1.0


def _segments_cross(p, q):
    """``(n, m)``: whether segment i of ``p`` and segment j of ``q`` (``(n, 4)``, ``(m, 4)``) share any point."""
    a, b = p[:, None, 0:2], p[:, None, 2:4]
    c, d = q[None, :, 0:2], q[None, :, 2:4]

    def orient(u, v, w):
        return np.sign(
            (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])
        )

    def on(u, v, w):  # w on segment uv, given collinear
        lo, hi = np.minimum(u, v), np.maximum(u, v)
        return ((w >= lo) & (w <= hi)).all(axis=-1)

    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    touching = (
        ((o1 == 0) & on(a, b, c)) | ((o2 == 0) & on(a, b, d)) | ((o3 == 0) & on(c, d, a)) | ((o4 == 0) & on(c, d, b))
    )
    return proper | touching


class BumperMap:
    """A validated map: polygons, their packed wall segments, and the wall cells touched-length is counted in.

    Args:
        polygons: the outline, then obstacle polygons; each ``(n, 2)`` vertices (cm), either orientation.
        name: a label for messages and renderings.

    Attributes:
        polygons: list of ``(n, 2)`` float64 vertex arrays.
        segments: ``(S, 4)`` wall segments ``(x1, y1, x2, y2)``, polygon by polygon.
        walls: ``(S, 6)`` the same, packed for the kernels (:func:`polyenvs.core.geometry2d.pack_segments`), with
            column 5 (nonzero: a real segment) the side of free space, +1 left of the segment, -1 right.
        bounds: ``(x_min, y_min, x_max, y_max)``.
        wall_length_cm: total length of the segments.
    """

    def __init__(self, polygons, name: str = "custom"):
        self.name = name
        self.polygons = _check_polygons(polygons)
        segs = [np.concatenate([p, np.roll(p, -1, axis=0)], axis=1) for p in self.polygons]
        self.segments = np.concatenate(segs)
        self._check_simple()
        # Column 5 of the packed walls, nonzero for a real segment, is the side free space lies on: +1 left of the
        # segment's direction, -1 right (the cart's contact search needs it; every kernel tests it against 0 only).
        self.walls = pack_segments(self.segments)
        self.walls[:, 5] = np.concatenate([np.full(len(p), _free_side(p, i == 0)) for i, p in enumerate(self.polygons)])
        every = np.concatenate(self.polygons)
        self.bounds = (*every.min(axis=0).tolist(), *every.max(axis=0).tolist())
        lengths = np.hypot(self.segments[:, 2] - self.segments[:, 0], self.segments[:, 3] - self.segments[:, 1])
        self.segment_lengths = lengths
        self.wall_length_cm = float(lengths.sum())

    def _check_simple(self) -> None:
        cross = _segments_cross(self.segments, self.segments)
        # Neighbouring edges of one polygon share a vertex; nothing else may touch.
        owner = np.concatenate([np.full(len(p), i) for i, p in enumerate(self.polygons)])
        index = np.concatenate([np.arange(len(p)) for p in self.polygons])
        sizes = np.array([len(p) for p in self.polygons])[owner]
        same = owner[:, None] == owner[None, :]
        gap = (index[:, None] - index[None, :]) % sizes[:, None]
        neighbour = same & ((gap == 1) | (gap == sizes[:, None] - 1) | (gap == 0))
        bad = cross & ~neighbour
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ValueError(f"map: edges {self.segments[i].tolist()} and {self.segments[j].tolist()} intersect")
        # Collinear neighbours that fold back over each other are not caught above.
        for p in self.polygons:
            e1, e2 = np.roll(p, -1, axis=0) - p, p - np.roll(p, 1, axis=0)
            folded = (np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 1e-12) & ((e1 * e2).sum(axis=1) < 0)
            if folded.any():
                raise ValueError(f"map: a polygon folds back on itself at vertex {p[np.argmax(folded)].tolist()}")
        outline = pack_segments(self.segments[: len(self.polygons[0])])
        for p in self.polygons[1:]:
            if not all(free_at(x, y, outline) for x, y in p):
                raise ValueError("map: every obstacle must lie inside the outline (the first polygon)")
        for i, p in enumerate(self.polygons[1:], start=1):
            for j, q in enumerate(self.polygons[1:], start=1):
                if i != j and free_at(*p[0], pack_segments(np.concatenate([q, np.roll(q, -1, axis=0)], axis=1))):
                    raise ValueError("map: obstacles must not contain one another")

    def free(self, points) -> np.ndarray:
        """Whether each ``(..., 2)`` point lies in free space."""
        return self.clearance(points) > 0.0

    def clearance(self, points) -> np.ndarray:
        """Distance to the nearest wall, positive in free space and negative inside walls or outside."""
        points = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(points.reshape(-1, 2))
        out = np.empty(len(flat))
        _free_clearance(flat, self.walls, out)
        return out.reshape(points.shape[:-1])

    @functools.cached_property
    def _free_grid(self) -> np.ndarray:
        """Centres of a grid over the map (1 cm cells, coarser for maps over 4 m so that it stays under 160,000
        points) with their clearance: ``(n, 3)``."""
        x0, y0, x1, y1 = self.bounds
        step = max(1.0, max(x1 - x0, y1 - y0) / 400.0)
        xs, ys = np.arange(x0 + 0.5 * step, x1, step), np.arange(y0 + 0.5 * step, y1, step)
        grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
        return np.concatenate([grid, self.clearance(grid)[:, None]], axis=1)

    def has_room(self, clearance_cm: float) -> bool:
        return bool((self._free_grid[:, 2] >= clearance_cm).any())

    def sample_pose(self, rng: np.random.Generator, clearance_cm: float) -> np.ndarray:
        """A pose ``(x, y, heading_rad)`` uniform over the free points at least ``clearance_cm`` from every wall,
        heading uniform (rejection sampling: the map was checked to have room)."""
        x0, y0, x1, y1 = self.bounds
        while True:
            x, y = x0 + (x1 - x0) * rng.random(), y0 + (y1 - y0) * rng.random()
            if _point_clearance(x, y, self.walls) >= clearance_cm:
                return np.array([x, y, 2.0 * np.pi * rng.random()])

    def wall_cells(self, cell_cm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each segment cut into equal cells of at most ``cell_cm``: ``(first cell, cell count)`` per segment
        (int64) and the length of each cell (cm)."""
        counts = np.maximum(np.ceil(self.segment_lengths / cell_cm - 1e-9), 1).astype(np.int64)
        first = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        return first, counts, np.repeat(self.segment_lengths / counts, counts)

    def __repr__(self) -> str:
        return f"BumperMap({self.name!r}, {len(self.polygons)} polygons, {len(self.segments)} walls)"


def _check_polygons(polygons) -> list[np.ndarray]:
    if isinstance(polygons, np.ndarray) and polygons.ndim == 2:
        polygons = [polygons]
    try:
        polys = [np.asarray(p, dtype=np.float64) for p in polygons]
        if polys and polys[0].ndim == 1:  # a single polygon given as a list of points
            polys = [np.asarray(polygons, dtype=np.float64)]
    except (TypeError, ValueError):
        raise ValueError("map must be a map name or a list of polygons, each a list of (x, y) vertices") from None
    if not polys:
        raise ValueError("map has no polygons")
    total = 0
    for p in polys:
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
            raise ValueError(f"map: every polygon needs at least 3 (x, y) vertices, got shape {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError("map: vertices must be finite")
        if np.abs(p).max() > 1e6:
            raise ValueError("map: vertices must lie within ±1e6 cm")
        edges = np.hypot(*(np.roll(p, -1, axis=0) - p).T)
        if edges.min() < MIN_EDGE_CM:
            raise ValueError(f"map: edges must be at least {MIN_EDGE_CM} cm long, got {edges.min():.3g} cm")
        total += len(p)
    if total > MAX_SEGMENTS:
        raise ValueError(f"map has {total} edges; at most {MAX_SEGMENTS} are supported")
    every = np.concatenate(polys)
    extent = float((every.max(axis=0) - every.min(axis=0)).max())
    if extent > MAX_EXTENT_CM:
        raise ValueError(f"map spans {extent:g} cm; at most {MAX_EXTENT_CM:g} cm is supported")
    return polys


def make_map(spec, clearance_cm: float = 0.0) -> BumperMap:
    """A :class:`BumperMap` from a built-in name, a polygon list or a map; raises ``ValueError`` naming ``map``.

    ``clearance_cm``: the map must have a free point this far from every wall (room for the cart).
    """
    if isinstance(spec, BumperMap):
        world = spec
    elif isinstance(spec, str):
        if spec not in MAPS:
            raise ValueError(f"map must be one of {sorted(MAPS)} or a list of polygons, got {spec!r}")
        world = _builtin(spec)
    else:
        world = BumperMap(spec)
    # A margin over the needed clearance, so the start poses drawn by rejection fill an area, not a point.
    if clearance_cm > 0 and not world.has_room(clearance_cm + 0.5):
        raise ValueError(
            f"map {world.name!r} has no free point {clearance_cm:g} cm from every wall: the cart does not fit"
        )
    return world


@functools.cache
def _builtin(name: str) -> BumperMap:
    return BumperMap(MAPS[name], name=name)


#: The split of the layouts (:mod:`polyenvs.core.layouts`): the room's width, train 90-140 cm, test 150-200 cm.
LAYOUT_SPLIT = LayoutSplit(
    (SplitParameter("room width", "cm", train=(90.0, 140.0), test=(150.0, 200.0)),),
    varies="a random room (a rectangle 70-120 cm deep, one corner cut at 45° half the time, up to two boxes)",
)
#: Every layout room lies in this box (x_min, y_min, x_max, y_max), so frames keep one size.
LAYOUT_ROOM_BOUNDS = (0.0, 0.0, LAYOUT_SPLIT.parameters[0].test[1], 120.0)
_DEPTHS_CM = (70.0, 120.0)
_CUT_CM = (15.0, 35.0)
_BOX_CM = (8.0, 20.0)
#: Boxes stand at least this far from the walls and from each other (cm), room for the cart (12 cm long) to pass.
_BOX_GAP_CM = 25.0
_MAX_BOXES = 2
#: The most edges a layout room has: a five-sided outline and two boxes.
LAYOUT_MAX_SEGMENTS = 5 + 4 * _MAX_BOXES


#: The kinds of feature the layout rooms hold (:func:`map_kinds` finds them in a map).
BOX = LayoutKind("box", "an obstacle polygon inside the outline, which the cart bumps from every side")
LAYOUT_KINDS = (DIAGONAL_WALL, BOX)


def map_kinds(world: BumperMap) -> frozenset[str]:
    """The names of the :data:`LAYOUT_KINDS` that ``world`` holds."""
    return frozenset(wall_direction_kinds(world.segments) | ({BOX.name} if len(world.polygons) > 1 else set()))


def episode_kinds(env) -> frozenset[str]:
    """:func:`map_kinds` of the map of a cart environment's (row 0's) episode."""
    return map_kinds(env.world)


def _uniform(rng: np.random.Generator, interval) -> float:
    return interval[0] + (interval[1] - interval[0]) * rng.random()


def random_room_map(rng: np.random.Generator, widths: tuple[float, float]) -> BumperMap:
    """A random room ``widths`` cm wide from ``rng``: a rectangle 70-120 cm deep, its north-west corner cut at 45°
    half the time (as the paper's arena is), and 0-2 boxes of 8-20 cm, each at least 25 cm from the walls and from
    each other (placed by rejection; a box that finds no place is left out)."""
    width, depth = _uniform(rng, widths), _uniform(rng, _DEPTHS_CM)
    outline = [(0.0, 0.0), (width, 0.0), (width, depth)]
    if rng.random() < 0.5:
        cut = _uniform(rng, _CUT_CM)
        outline += [(cut, depth), (0.0, depth - cut)]
    else:
        outline.append((0.0, depth))
    room = BumperMap([outline])
    boxes: list[tuple[float, float, float, float]] = []
    for _ in range(int(rng.integers(0, _MAX_BOXES + 1))):
        for _ in range(20):
            w, h = _uniform(rng, _BOX_CM), _uniform(rng, _BOX_CM)
            x, y = _uniform(rng, (0.0, width - w)), _uniform(rng, (0.0, depth - h))
            corners = np.array([(x, y), (x + w, y), (x + w, y + h), (x, y + h)])
            apart = all(
                x > bx + bw + _BOX_GAP_CM or bx > x + w + _BOX_GAP_CM or y > by + bh + _BOX_GAP_CM
                or by > y + h + _BOX_GAP_CM
                for bx, by, bw, bh in boxes
            )  # fmt: skip
            if apart and (room.clearance(corners) >= _BOX_GAP_CM).all():
                boxes.append((x, y, w, h))
                break
    return BumperMap([outline, *(_box(x, y, x + w, y + h) for x, y, w, h in boxes)], name="random room")


def layout_map(rng: np.random.Generator, layouts: str) -> BumperMap:
    """A room of the ``layouts`` ("train" or "test") distribution, drawn from ``rng``."""
    return random_room_map(rng, LAYOUT_SPLIT.parameters[0].interval(layouts))
