"""Planar geometry against wall segments: ray casting, clearance and swept motion, compiled and batched.

Walls live in one packed array, ``(W, S, 6)`` float64, a row per segment: start x, start y, direction x,
direction y (end minus start), 1 / squared length, and 1.0 for a real segment (0.0 for padding). ``W`` is 1 (one
wall set shared by every robot) or the batch size (a wall set per environment, padded to a common ``S``). Padding
rows have zero length and every kernel skips them, so padding never changes a result.

Conventions for compiled code, here and in every family's simulator:

- Pack state into a few contiguous arrays with named column constants: numba unboxes each array argument on every
  call (about 0.05 µs each), so a kernel with twenty arguments costs more than the arithmetic it does.
- Scalar kernels (``ray_distance``, ``nearest_point``, ``segment_crosses``) take one wall set ``walls[w]`` and are
  called from other compiled loops; the batched wrappers below are for numpy callers.
- A kernel indexes only rows and columns it was given; the test suite runs once with ``NUMBA_BOUNDSCHECK=1``.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = [
    "WALL_COLUMNS",
    "SegmentTable",
    "cast_rays",
    "crossings",
    "first_hits",
    "nearest_point",
    "nearest_squared",
    "nearest_wall_points",
    "pack_segments",
    "point_segment_distance_sq",
    "ray_circle_hit",
    "ray_distance",
    "ray_segment_hit",
    "segment_crosses",
]

#: Columns of a packed wall row.
WALL_COLUMNS = ("start_x", "start_y", "vector_x", "vector_y", "inv_length_sq", "is_real")
_SX, _SY, _VX, _VY, _INV, _REAL = range(6)


def pack_segments(segments: np.ndarray, n_rows: int | None = None) -> np.ndarray:
    """``(S, 4)`` segments ``(x1, y1, x2, y2)`` as packed wall rows ``(n_rows, 6)`` (zero-length padding after S)."""
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    n_rows = len(seg) if n_rows is None else int(n_rows)
    if n_rows < len(seg):
        raise ValueError(f"{len(seg)} segments do not fit in {n_rows} rows")
    packed = np.zeros((n_rows, 6))
    vector = seg[:, 2:4] - seg[:, 0:2]
    length_sq = (vector**2).sum(axis=1)
    real = length_sq > 0.0
    packed[: len(seg), 0:2] = seg[:, 0:2]
    packed[: len(seg), 2:4] = vector
    packed[: len(seg), _INV] = np.where(real, 1.0 / np.where(real, length_sq, 1.0), 0.0)
    packed[: len(seg), _REAL] = real
    return packed


class SegmentTable:
    """Wall segments packed for the kernels.

    Args:
        segments: ``(W, S, 4)`` or ``(S, 4)`` array of wall segments (x1, y1, x2, y2).
    """

    def __init__(self, segments: np.ndarray):
        seg = np.asarray(segments, dtype=np.float64)
        if seg.ndim == 2:
            seg = seg[None]
        self.segments = seg
        self.packed = np.stack([pack_segments(s) for s in seg])  # (W, S, 6)

    @property
    def batch_size(self) -> int:
        return self.packed.shape[0]


@njit(cache=True, inline="always")
def ray_segment_hit(ray, segment, best):
    """The smaller of ``best`` and the distance along the ray ``(ox, oy, dx, dy)`` to the segment ``(sx, sy, ex,
    ey)`` (start, then end minus start); a ray parallel to the segment never hits it. Scalars in tuples, inlined into
    compiled loops (a tuple costs nothing there)."""
    ox, oy, dx, dy = ray
    sx, sy, ex, ey = segment
    denom = dx * ey - dy * ex
    if denom == 0.0:
        return best
    qx, qy = sx - ox, sy - oy
    t = (qx * ey - qy * ex) / denom
    u = (qx * dy - qy * dx) / denom
    if 0.0 <= t < best and 0.0 <= u <= 1.0:
        return t
    return best


@njit(cache=True, inline="always")
def ray_circle_hit(ray, circle, best):
    """The smaller of ``best`` and the distance along the unit ray ``(ox, oy, dx, dy)`` to the circle ``(cx, cy,
    r)``: 0 when the ray starts inside it."""
    ox, oy, dx, dy = ray
    cx, cy, r = circle
    fx, fy = ox - cx, oy - cy
    c = fx * fx + fy * fy - r * r
    if c <= 0.0:
        return 0.0
    b = fx * dx + fy * dy
    if b >= 0.0:
        return best
    disc = b * b - c
    if disc < 0.0:
        return best
    t = -b - math.sqrt(disc)
    return t if t < best else best


@njit(cache=True, inline="always")
def point_segment_distance_sq(px, py, segment):
    """Squared distance from (px, py) to the segment ``(x0, y0, x1, y1)`` (its end points)."""
    x0, y0, x1, y1 = segment
    dx, dy = x1 - x0, y1 - y0
    length_sq = dx * dx + dy * dy
    t = 0.0
    if length_sq > 0.0:
        t = min(max(((px - x0) * dx + (py - y0) * dy) / length_sq, 0.0), 1.0)
    ex, ey = x0 + t * dx - px, y0 + t * dy - py
    return ex * ex + ey * ey


@njit(cache=True)
def ray_distance(ox, oy, dx, dy, walls):
    """Distance along the ray (o, d) to the first wall of ``walls`` (S, 6); ``inf`` if none."""
    best = math.inf
    for k in range(walls.shape[0]):
        if walls[k, _REAL] != 0.0:
            best = ray_segment_hit((ox, oy, dx, dy), (walls[k, _SX], walls[k, _SY], walls[k, _VX], walls[k, _VY]), best)
    return best


@njit(cache=True)
def nearest_point(px, py, walls):
    """Nearest wall point to (px, py): ``(distance, foot_x, foot_y, segment index)``."""
    best, fx, fy, index = math.inf, math.nan, math.nan, -1
    for k in range(walls.shape[0]):
        if walls[k, _REAL] == 0.0:
            continue
        sx, sy, ex, ey = walls[k, _SX], walls[k, _SY], walls[k, _VX], walls[k, _VY]
        along = ((px - sx) * ex + (py - sy) * ey) * walls[k, _INV]
        along = min(max(along, 0.0), 1.0)
        qx, qy = sx + along * ex, sy + along * ey
        d2 = (px - qx) ** 2 + (py - qy) ** 2
        if d2 < best:
            best, fx, fy, index = d2, qx, qy, k
    return math.sqrt(best), fx, fy, index


@njit(cache=True)
def segment_crosses(ax, ay, bx, by, walls):
    """Whether the motion from (ax, ay) to (bx, by) touches any wall (shared points count as touching)."""
    mx, my = bx - ax, by - ay
    for k in range(walls.shape[0]):
        if walls[k, _REAL] == 0.0:
            continue
        ex, ey = walls[k, _VX], walls[k, _VY]
        qx, qy = walls[k, _SX] - ax, walls[k, _SY] - ay
        denom = mx * ey - my * ex
        if denom == 0.0:
            # Parallel: they touch only if collinear and overlapping.
            if qx * my - qy * mx != 0.0:
                continue
            length_sq = mx * mx + my * my
            if length_sq == 0.0:
                continue
            t0 = (qx * mx + qy * my) / length_sq
            t1 = ((qx + ex) * mx + (qy + ey) * my) / length_sq
            if max(t0, t1) >= 0.0 and min(t0, t1) <= 1.0:
                return True
            continue
        t = (qx * ey - qy * ex) / denom
        u = (qx * my - qy * mx) / denom
        if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
            return True
    return False


@njit(cache=True)
def _cast_rays(walls, origins, directions, out):
    shared = walls.shape[0] == 1
    for b in range(origins.shape[0]):
        w = 0 if shared else b
        for r in range(origins.shape[1]):
            out[b, r] = ray_distance(
                origins[b, r, 0], origins[b, r, 1], directions[b, r, 0], directions[b, r, 1], walls[w]
            )


@njit(cache=True)
def _nearest(walls, points, distance, foot, segment):
    shared = walls.shape[0] == 1
    for b in range(points.shape[0]):
        w = 0 if shared else b
        for p in range(points.shape[1]):
            d, fx, fy, k = nearest_point(points[b, p, 0], points[b, p, 1], walls[w])
            distance[b, p], foot[b, p, 0], foot[b, p, 1], segment[b, p] = d, fx, fy, k


def _check_batch(table: SegmentTable, batch: int) -> None:
    if table.batch_size not in (1, batch):
        raise ValueError(f"walls batch {table.batch_size} does not match the query batch {batch}")


def cast_rays(table: SegmentTable, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each ray to the first wall (``inf`` where none is hit).

    Args:
        table: walls, shared (W = 1) or one set per batch row.
        origins: ``(B, R, 2)`` ray origins.
        directions: ``(B, R, 2)`` unit ray directions.

    Returns:
        ``(B, R)`` distances.
    """
    origins = np.ascontiguousarray(origins, dtype=np.float64)
    directions = np.ascontiguousarray(np.broadcast_to(directions, origins.shape), dtype=np.float64)
    _check_batch(table, origins.shape[0])
    out = np.empty(origins.shape[:2])
    _cast_rays(table.packed, origins, directions, out)
    return out


def nearest_wall_points(table: SegmentTable, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest wall point to each query point.

    Args:
        table: walls, shared (W = 1) or one set per batch row.
        points: ``(B, P, 2)`` query points.

    Returns:
        ``(distance, foot, segment)``: ``(B, P)`` distances, ``(B, P, 2)`` nearest wall points and ``(B, P)``
        indices of the segment they lie on.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    _check_batch(table, points.shape[0])
    distance = np.empty(points.shape[:2])
    foot = np.empty(points.shape)
    segment = np.empty(points.shape[:2], dtype=np.int64)
    _nearest(table.packed, points, distance, foot, segment)
    return distance, foot, segment


# --- Batched, branch-free kernels: walls in the outer loop, queries inner, so the compiler vectorises them ------
# Queries are flat arrays in groups of ``per`` consecutive entries (a robot's rays, say), the first ``n`` entries
# used; ``queries = (owners, per, n)``. With one shared wall set (W = 1) every query meets every wall in one sweep;
# with a wall set per robot, group g meets walls[owners[g]]. The query coordinates come as one tuple of flat
# arrays. They give exactly the scalar kernels' numbers (same operations, same wall order, no fast-math).


@njit(cache=True, error_model="numpy")
def _rays_against(ws, lo, hi, ox, oy, dx, dy, best):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    for k in range(ws.shape[0]):
        if ws[k, _REAL] == 0.0:
            continue
        sx, sy, ex, ey = ws[k, _SX], ws[k, _SY], ws[k, _VX], ws[k, _VY]
        for j in range(lo, hi):
            denom = dx[j] * ey - dy[j] * ex  # 0 for a parallel ray: t and u become inf or nan and never hit
            qx, qy = sx - ox[j], sy - oy[j]
            t = (qx * ey - qy * ex) / denom
            u = (qx * dy[j] - qy * dx[j]) / denom
            hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0) & (t < best[j])
            best[j] = t if hit else best[j]


@njit(cache=True, error_model="numpy")
def first_hits(walls, queries, rays, best):
    """``best[:n]``: distance along each ray ``rays = (ox, oy, dx, dy)`` to the first wall (``inf`` if none); as
    ``ray_distance``. ``queries = (owners, per, n)``."""
    owners, per, n = queries
    ox, oy, dx, dy = rays
    for j in range(n):
        best[j] = math.inf
    if walls.shape[0] == 1:
        _rays_against(walls[0], 0, n, ox, oy, dx, dy, best)
    else:
        for g in range(n // per):
            _rays_against(walls[owners[g]], g * per, (g + 1) * per, ox, oy, dx, dy, best)


@njit(cache=True, error_model="numpy")
def _nearest_against(ws, lo, hi, px, py, best, index):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    for k in range(ws.shape[0]):
        if ws[k, _REAL] == 0.0:
            continue
        sx, sy, ex, ey, inv = ws[k, _SX], ws[k, _SY], ws[k, _VX], ws[k, _VY], ws[k, _INV]
        for j in range(lo, hi):
            along = min(max(((px[j] - sx) * ex + (py[j] - sy) * ey) * inv, 0.0), 1.0)
            gx, gy = px[j] - (sx + along * ex), py[j] - (sy + along * ey)
            d2 = gx * gx + gy * gy
            better = d2 < best[j]
            best[j] = d2 if better else best[j]
            index[j] = k if better else index[j]


@njit(cache=True, error_model="numpy")
def nearest_squared(walls, queries, points, best, index):
    """``best[:n]``: squared distance from each point of ``points = (px, py)`` to the nearest wall, ``index[:n]``
    that wall (as ``nearest_point``, which also gives the foot). ``queries = (owners, per, n)``."""
    owners, per, n = queries
    px, py = points
    for j in range(n):
        best[j] = math.inf
        index[j] = -1.0
    if walls.shape[0] == 1:
        _nearest_against(walls[0], 0, n, px, py, best, index)
    else:
        for g in range(n // per):
            _nearest_against(walls[owners[g]], g * per, (g + 1) * per, px, py, best, index)


@njit(cache=True, error_model="numpy")
def _crossings_against(ws, lo, hi, ax, ay, bx, by, hit):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    for k in range(ws.shape[0]):
        if ws[k, _REAL] == 0.0:
            continue
        sx, sy, ex, ey = ws[k, _SX], ws[k, _SY], ws[k, _VX], ws[k, _VY]
        for j in range(lo, hi):
            mx, my = bx[j] - ax[j], by[j] - ay[j]
            qx, qy = sx - ax[j], sy - ay[j]
            denom = mx * ey - my * ex
            t = (qx * ey - qy * ex) / denom
            u = (qx * my - qy * mx) / denom
            crossing = (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
            # Parallel and on the same line: they touch if their extents overlap along the motion.
            length_sq = mx * mx + my * my
            t0 = (qx * mx + qy * my) / length_sq
            t1 = ((qx + ex) * mx + (qy + ey) * my) / length_sq
            overlap = (denom == 0.0) & (qx * my - qy * mx == 0.0) & (max(t0, t1) >= 0.0) & (min(t0, t1) <= 1.0)
            hit[j] = 1.0 if (hit[j] > 0.5) | crossing | overlap else 0.0


@njit(cache=True, error_model="numpy")
def crossings(walls, queries, motions, hit):
    """``hit[:n]``: 1 where the motion from a to b of ``motions = (ax, ay, bx, by)`` touches a wall, else 0 (as
    ``segment_crosses``). ``queries = (owners, per, n)``."""
    owners, per, n = queries
    ax, ay, bx, by = motions
    for j in range(n):
        hit[j] = 0.0
    if walls.shape[0] == 1:
        _crossings_against(walls[0], 0, n, ax, ay, bx, by, hit)
    else:
        for g in range(n // per):
            _crossings_against(walls[owners[g]], g * per, (g + 1) * per, ax, ay, bx, by, hit)
