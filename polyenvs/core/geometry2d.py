"""Planar geometry against wall segments: ray casting and clearance, compiled and batched.

Walls are segments ``(x1, y1, x2, y2)`` held in a :class:`SegmentTable` of shape ``(W, S)``: ``W`` is 1 (one wall
set shared by every robot) or the batch size (one set per environment). Padding segments (for batches whose plans
have different numbers of walls) have zero length and are ignored. The scalar kernels ``ray_distance`` and
``nearest_point`` can be called from other compiled code (each family's simulator); ``cast_rays`` and
``nearest_wall_points`` are their batched numpy-facing forms.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = ["SegmentTable", "cast_rays", "nearest_point", "nearest_wall_points", "ray_distance"]


class SegmentTable:
    """Wall segments with the terms every query reuses: start points, direction vectors, 1 / squared length.

    Args:
        segments: ``(W, S, 4)`` or ``(S, 4)`` array of wall segments (x1, y1, x2, y2).
    """

    def __init__(self, segments: np.ndarray):
        seg = np.asarray(segments, dtype=np.float64)
        if seg.ndim == 2:
            seg = seg[None]
        self.segments = seg
        self.start = np.ascontiguousarray(seg[..., 0:2])  # (W, S, 2)
        self.vector = np.ascontiguousarray(seg[..., 2:4] - seg[..., 0:2])
        length_sq = (self.vector**2).sum(axis=-1)
        self.is_real = length_sq > 0.0
        self.inv_length_sq = np.where(self.is_real, 1.0 / np.where(self.is_real, length_sq, 1.0), 0.0)

    @property
    def batch_size(self) -> int:
        return self.segments.shape[0]


@njit(cache=True)
def ray_distance(ox, oy, dx, dy, start, vector, is_real):
    """Distance along the ray (o, d) to the first of the segments ``start``/``vector`` (S, 2); ``inf`` if none."""
    best = math.inf
    for k in range(start.shape[0]):
        if not is_real[k]:
            continue
        ex, ey = vector[k, 0], vector[k, 1]
        denom = dx * ey - dy * ex
        if denom == 0.0:
            continue  # parallel
        qx, qy = start[k, 0] - ox, start[k, 1] - oy
        t = (qx * ey - qy * ex) / denom
        u = (qx * dy - qy * dx) / denom
        if t >= 0.0 and 0.0 <= u <= 1.0 and t < best:
            best = t
    return best


@njit(cache=True)
def nearest_point(px, py, start, vector, inv_length_sq, is_real):
    """Nearest point of the segments to (px, py): ``(distance, foot_x, foot_y, segment index)``."""
    best, fx, fy, index = math.inf, math.nan, math.nan, -1
    for k in range(start.shape[0]):
        if not is_real[k]:
            continue
        sx, sy, ex, ey = start[k, 0], start[k, 1], vector[k, 0], vector[k, 1]
        along = ((px - sx) * ex + (py - sy) * ey) * inv_length_sq[k]
        along = min(max(along, 0.0), 1.0)
        qx, qy = sx + along * ex, sy + along * ey
        d2 = (px - qx) ** 2 + (py - qy) ** 2
        if d2 < best:
            best, fx, fy, index = d2, qx, qy, k
    return math.sqrt(best), fx, fy, index


@njit(cache=True)
def _cast_rays(start, vector, is_real, origins, directions, out):
    shared = start.shape[0] == 1
    for b in range(origins.shape[0]):
        w = 0 if shared else b
        for r in range(origins.shape[1]):
            out[b, r] = ray_distance(
                origins[b, r, 0],
                origins[b, r, 1],
                directions[b, r, 0],
                directions[b, r, 1],
                start[w],
                vector[w],
                is_real[w],
            )


@njit(cache=True)
def _nearest(start, vector, inv_length_sq, is_real, points, distance, foot, segment):
    shared = start.shape[0] == 1
    for b in range(points.shape[0]):
        w = 0 if shared else b
        for p in range(points.shape[1]):
            d, fx, fy, k = nearest_point(
                points[b, p, 0], points[b, p, 1], start[w], vector[w], inv_length_sq[w], is_real[w]
            )
            distance[b, p], foot[b, p, 0], foot[b, p, 1], segment[b, p] = d, fx, fy, k


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
    out = np.empty(origins.shape[:2])
    _cast_rays(table.start, table.vector, table.is_real, origins, directions, out)
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
    distance = np.empty(points.shape[:2])
    foot = np.empty(points.shape)
    segment = np.empty(points.shape[:2], dtype=np.int64)
    _nearest(table.start, table.vector, table.inv_length_sq, table.is_real, points, distance, foot, segment)
    return distance, foot, segment
