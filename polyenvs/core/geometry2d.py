"""Batched planar geometry against wall segments: ray casting and clearance.

Walls are segments ``(x1, y1, x2, y2)`` in an array of shape ``(..., S, 4)``. Every function broadcasts a leading
batch axis so that one environment (batch of one) and a vector of environments share the same arithmetic.
Padding segments (for batches whose plans have different numbers of walls) are zero-length, which never hits a
ray and is given infinite distance.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SegmentTable", "cast_rays", "nearest_wall_points"]


class SegmentTable:
    """Precomputed terms of a batch of wall sets: start points, direction vectors, squared lengths.

    Args:
        segments: ``(B, S, 4)`` or ``(S, 4)`` array of wall segments (x1, y1, x2, y2).
    """

    def __init__(self, segments: np.ndarray):
        seg = np.asarray(segments, dtype=np.float64)
        if seg.ndim == 2:
            seg = seg[None]
        self.segments = seg
        self.start = seg[..., 0:2]  # (B, S, 2)
        self.vector = seg[..., 2:4] - seg[..., 0:2]
        self.length_sq = np.einsum("bsk,bsk->bs", self.vector, self.vector)
        self.is_real = self.length_sq > 0.0
        # Zero-length padding: make the reciprocal finite; the distance test masks these segments out.
        self.inv_length_sq = np.where(self.is_real, 1.0 / np.where(self.is_real, self.length_sq, 1.0), 0.0)
        # start x vector, reused by every ray cast.
        self.start_cross_vector = self.start[..., 0] * self.vector[..., 1] - self.start[..., 1] * self.vector[..., 0]

    @property
    def batch_size(self) -> int:
        return self.segments.shape[0]


def cast_rays(table: SegmentTable, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each ray to the first wall (``inf`` where none is hit).

    Args:
        table: walls of shape (B, S).
        origins: ``(B, R, 2)`` ray origins.
        directions: ``(B, R, 2)`` unit ray directions.

    Returns:
        ``(B, R)`` distances.
    """
    ox, oy = origins[..., 0:1], origins[..., 1:2]  # (B, R, 1)
    dx, dy = directions[..., 0:1], directions[..., 1:2]
    sx, sy = table.start[:, None, :, 0], table.start[:, None, :, 1]  # (B, 1, S)
    ex, ey = table.vector[:, None, :, 0], table.vector[:, None, :, 1]
    # Solve o + t d = s + u e with 2-D cross products.
    denom = dx * ey - dy * ex  # (B, R, S)
    t_num = table.start_cross_vector[:, None, :] - (ox * ey - oy * ex)
    u_num = (sx - ox) * dy - (sy - oy) * dx
    with np.errstate(divide="ignore", invalid="ignore"):
        t = t_num / denom
        u = u_num / denom
    hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
    return np.where(hit, t, np.inf).min(axis=-1)


def nearest_wall_points(table: SegmentTable, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest wall point to each query point.

    Args:
        table: walls of shape (B, S).
        points: ``(B, P, 2)`` query points.

    Returns:
        ``(distance, foot, segment)``: ``(B, P)`` distances, ``(B, P, 2)`` nearest wall points and ``(B, P)``
        indices of the segment they lie on.
    """
    px, py = points[..., 0:1], points[..., 1:2]  # (B, P, 1)
    sx, sy = table.start[:, None, :, 0], table.start[:, None, :, 1]  # (B or 1, 1, S): shared walls broadcast
    ex, ey = table.vector[:, None, :, 0], table.vector[:, None, :, 1]
    along = ((px - sx) * ex + (py - sy) * ey) * table.inv_length_sq[:, None, :]
    np.clip(along, 0.0, 1.0, out=along)
    fx, fy = sx + along * ex, sy + along * ey  # (B, P, S)
    dist_sq = (px - fx) ** 2 + (py - fy) ** 2
    if not table.is_real.all():
        dist_sq = np.where(table.is_real[:, None, :], dist_sq, np.inf)
    segment = dist_sq.argmin(axis=-1)  # (B, P)
    b, p = np.indices(segment.shape, sparse=True)
    foot = np.empty(points.shape)
    foot[..., 0], foot[..., 1] = fx[b, p, segment], fy[b, p, segment]
    return np.sqrt(dist_sq[b, p, segment]), foot, segment
