"""A tiny numpy rasterizer for top-down RGB frames of planar robots.

``Canvas`` maps a world rectangle (y up) onto an ``(H, W, 3)`` uint8 image (row 0 at the top) and draws the few
primitives a planar scene needs: segments (walls, beams), polylines (paths), filled polygons (robot bodies), discs
and point markers. There is no anti-aliasing. Every primitive is drawn with a constant number of numpy calls
whatever the number of points, so a full frame takes on the order of a millisecond.

Pixel convention: :meth:`Canvas.to_pixels` returns continuous ``(col, row)`` coordinates in which pixel ``(c, r)``
covers ``[c, c + 1) x [r, r + 1)``; its centre is ``(c + 0.5, r + 0.5)``. Area fills (polygons, discs) test pixel
centres; strokes (lines, markers) paint the pixel each sample falls in, plus a disc-shaped footprint of neighbours.

Everything clips silently to the image, non-finite points are skipped and empty inputs draw nothing.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from polyenvs.core.validation import check_finite, check_positive

__all__ = ["Canvas"]

# At most half a pixel between samples along a stroke, so consecutive samples land in the same or adjacent pixels
# and a 1-px line has no gaps.
_SAMPLE_SPACING_PX = 0.5


@lru_cache(maxsize=32)
def _footprint(radius_px: float) -> tuple[np.ndarray, np.ndarray]:
    """``(drow, dcol)`` offsets of the pixels whose centres lie within ``radius_px`` of a pixel centre."""
    reach = int(math.floor(radius_px))
    d = np.arange(-reach, reach + 1)
    drow, dcol = np.meshgrid(d, d, indexing="ij")
    keep = drow * drow + dcol * dcol <= radius_px * radius_px
    keep[reach, reach] = True  # a stroke always paints at least the pixel it passes through
    drow, dcol = drow[keep], dcol[keep]
    drow.flags.writeable = False  # cached and shared between calls
    dcol.flags.writeable = False
    return drow, dcol


def _as_points(name: str, points) -> np.ndarray:
    """``points`` as a float64 ``(N, 2)`` array; any empty input becomes ``(0, 2)``."""
    p = np.asarray(points, dtype=np.float64)
    if p.size == 0:
        return p.reshape(0, 2)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {p.shape}")
    return p


def _as_colors(name: str, color, count: int) -> np.ndarray:
    """One RGB triple ``(3,)`` or one per item ``(count, 3)``, as uint8 in 0..255."""
    c = np.asarray(color, dtype=np.float64)
    if c.shape != (3,) and c.shape != (count, 3):
        raise ValueError(f"{name} must be an RGB triple or have shape ({count}, 3), got {c.shape}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} must be finite")
    return np.clip(np.rint(c), 0, 255).astype(np.uint8)


def _clip_segments(a: np.ndarray, b: np.ndarray, low: tuple[float, float], high: tuple[float, float]):
    """Liang-Barsky clipping of segments ``a -> b`` to a box; returns clipped ends and a keep mask.

    Clipping before sampling bounds the sample count by the frame size, so a wall a kilometre off-screen costs
    nothing and far-away coordinates never reach an integer cast.
    """
    d = b - a
    t0 = np.zeros(len(a))
    t1 = np.ones(len(a))
    keep = np.ones(len(a), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis in (0, 1):
            for p, q in ((-d[:, axis], a[:, axis] - low[axis]), (d[:, axis], high[axis] - a[:, axis])):
                keep &= (p != 0) | (q >= 0)  # parallel to this edge and outside it
                ratio = q / p
                t0 = np.where(p < 0, np.maximum(t0, ratio), t0)
                t1 = np.where(p > 0, np.minimum(t1, ratio), t1)
    keep &= t0 <= t1
    return a + t0[:, None] * d, a + t1[:, None] * d, keep


class Canvas:
    """An RGB image mapped onto a world rectangle (world units, y up; image row 0 at the top).

    Args:
        bounds: ``(xmin, ymin, xmax, ymax)`` of the region to show, in world units.
        width: image width in pixels.
        height: image height in pixels; ``None`` derives it from the aspect ratio of the (margined) bounds. When
            given, the scale is uniform anyway and the bounds are centred, leaving bands of background.
        margin: fraction of the larger side of ``bounds`` added on every side.
        background: RGB fill of the initial image.
    """

    def __init__(
        self,
        bounds: tuple[float, float, float, float],
        width: int = 480,
        height: int | None = None,
        margin: float = 0.05,
        background=(255, 255, 255),
    ):
        if len(bounds) != 4:
            raise ValueError(f"bounds must be (xmin, ymin, xmax, ymax), got {bounds!r}")
        xmin, ymin, xmax, ymax = (check_finite("bounds", v) for v in bounds)
        if xmax < xmin or ymax < ymin:
            raise ValueError(f"bounds must satisfy xmin <= xmax and ymin <= ymax, got {bounds!r}")
        margin = check_positive("margin", margin, allow_zero=True)
        if int(width) != width or width < 1:
            raise ValueError(f"width must be a positive integer, got {width!r}")
        if height is not None and (int(height) != height or height < 1):
            raise ValueError(f"height must be a positive integer or None, got {height!r}")

        pad = margin * max(xmax - xmin, ymax - ymin)
        span_x = xmax - xmin + 2 * pad
        span_y = ymax - ymin + 2 * pad
        # A degenerate (zero-extent) axis borrows the other's extent so the scale stays finite.
        if span_x <= 0 and span_y <= 0:
            span_x = span_y = 1.0
        elif span_x <= 0:
            span_x = span_y
        elif span_y <= 0:
            span_y = span_x
        self.width = int(width)
        self.height = max(1, round(self.width * span_y / span_x)) if height is None else int(height)
        self.scale = min(self.width / span_x, self.height / span_y)  # pixels per world unit
        self._centre = (0.5 * (xmin + xmax), 0.5 * (ymin + ymax))
        self.bounds = (xmin, ymin, xmax, ymax)
        self._image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._image[...] = _as_colors("background", background, 1)

    @property
    def image(self) -> np.ndarray:
        """The current frame, ``(H, W, 3)`` uint8 (a copy, safe to keep while drawing continues)."""
        return self._image.copy()

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """World ``(..., 2)`` -> continuous pixel coordinates ``(..., 2)`` as ``(col, row)``."""
        p = np.asarray(points, dtype=np.float64)
        if p.shape[-1:] != (2,):
            raise ValueError(f"points must have shape (..., 2), got {p.shape}")
        out = np.empty_like(p)
        out[..., 0] = (p[..., 0] - self._centre[0]) * self.scale + 0.5 * self.width
        out[..., 1] = 0.5 * self.height - (p[..., 1] - self._centre[1]) * self.scale
        return out

    def lines(self, starts, ends, color, width_px: float = 1.0) -> None:
        """Draw N segments ``starts[i] -> ends[i]`` (world ``(N, 2)``); ``color`` is RGB or ``(N, 3)``."""
        a = _as_points("starts", starts)
        b = _as_points("ends", ends)
        if a.shape != b.shape:
            raise ValueError(f"starts and ends must have the same shape, got {a.shape} and {b.shape}")
        colors = _as_colors("color", color, len(a))
        width_px = check_positive("width_px", width_px)
        if len(a) == 0:
            return
        self._stroke(self.to_pixels(a), self.to_pixels(b), colors, width_px)

    def polyline(self, points, color, width_px: float = 1.0) -> None:
        """Draw the connected path through ``points`` (world ``(N, 2)``); a NaN point breaks the path there."""
        p = _as_points("points", points)
        colors = _as_colors("color", color, 1)
        width_px = check_positive("width_px", width_px)
        if len(p) == 0:
            return
        px = self.to_pixels(p)
        if len(p) == 1:
            self._stroke(px, px, colors, width_px)
        else:
            self._stroke(px[:-1], px[1:], colors, width_px)

    def polygon(self, vertices, color, outline=None) -> None:
        """Fill the polygon ``vertices`` (world ``(V, 2)``), optionally with a 1-px ``outline`` colour.

        Filled by the even-odd rule, so any simple polygon works (convex or not) in either winding order.
        """
        v = _as_points("vertices", vertices)
        fill = _as_colors("color", color, 1)
        edge = None if outline is None else _as_colors("outline", outline, 1)
        v = v[np.isfinite(v).all(axis=1)]
        if len(v) == 0:
            return
        px = self.to_pixels(v)
        if len(v) >= 3:
            self._fill_polygon(px, fill)
        if edge is not None:
            self._stroke(px, np.roll(px, -1, axis=0), edge, 1.0)

    def disc(self, centre, radius, color) -> None:
        """Fill the disc of world ``radius`` around world ``centre``; at least the centre's pixel is painted."""
        c = np.asarray(centre, dtype=np.float64)
        if c.shape != (2,):
            raise ValueError(f"centre must have shape (2,), got {c.shape}")
        radius = check_positive("radius", radius, allow_zero=True)
        fill = _as_colors("color", color, 1)
        if not np.isfinite(c).all():
            return
        cx, cy = self.to_pixels(c)
        r = radius * self.scale
        c0, c1 = max(math.floor(cx - r), 0), min(math.floor(cx + r) + 1, self.width)
        r0, r1 = max(math.floor(cy - r), 0), min(math.floor(cy + r) + 1, self.height)
        if c0 >= c1 or r0 >= r1:
            return
        dx = np.arange(c0, c1) + 0.5 - cx
        dy = np.arange(r0, r1) + 0.5 - cy
        inside = dy[:, None] ** 2 + dx[None, :] ** 2 <= r * r
        # Sub-pixel discs would otherwise vanish; the centre pixel is always inside the clipped box if on-screen.
        if c0 <= cx < c1 and r0 <= cy < r1:
            inside[math.floor(cy) - r0, math.floor(cx) - c0] = True
        self._image[r0:r1, c0:c1][inside] = fill

    def points(self, points, color, radius_px: float = 1.5) -> None:
        """Draw a round marker of ``radius_px`` pixels at each world point ``(N, 2)``; ``color`` RGB or ``(N, 3)``."""
        p = _as_points("points", points)
        colors = _as_colors("color", color, len(p))
        radius_px = check_positive("radius_px", radius_px, allow_zero=True)
        if len(p) == 0:
            return
        px = self.to_pixels(p)
        reach = math.floor(radius_px) + 1
        on_screen = np.isfinite(px).all(axis=1)
        on_screen &= (px[:, 0] > -reach) & (px[:, 0] < self.width + reach)
        on_screen &= (px[:, 1] > -reach) & (px[:, 1] < self.height + reach)
        index = np.flatnonzero(on_screen)
        px = px[index]
        self._stamp(
            np.floor(px[:, 1]).astype(np.intp),
            np.floor(px[:, 0]).astype(np.intp),
            colors if colors.ndim == 1 else colors[index],
            radius_px,
        )

    def _stroke(self, a: np.ndarray, b: np.ndarray, colors: np.ndarray, width_px: float) -> None:
        """Draw pixel-space segments ``a -> b`` by sampling them densely and stamping a round footprint."""
        radius = 0.5 * width_px
        pad = math.floor(radius) + 1
        finite = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        a, b = a[finite], b[finite]
        a, b, keep = _clip_segments(a, b, (-pad, -pad), (self.width + pad, self.height + pad))
        index = np.flatnonzero(keep)
        if index.size == 0:
            return
        a, b = a[index], b[index]
        d = b - a
        count = np.ceil(np.hypot(d[:, 0], d[:, 1]) / _SAMPLE_SPACING_PX).astype(np.intp) + 1
        segment = np.repeat(np.arange(len(a)), count)
        first = np.cumsum(count) - count
        step = np.arange(segment.size) - first[segment]
        t = step / np.maximum(count - 1, 1)[segment]
        rows = np.floor(a[segment, 1] + t * d[segment, 1]).astype(np.intp)
        cols = np.floor(a[segment, 0] + t * d[segment, 0]).astype(np.intp)
        # Dense sampling hits each pixel about twice; dropping repeats halves the footprint work for thick strokes.
        fresh = np.ones(rows.size, dtype=bool)
        fresh[1:] = (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1])
        if colors.ndim == 1:
            self._stamp(rows[fresh], cols[fresh], colors, radius)
        else:
            self._stamp(rows[fresh], cols[fresh], colors[finite][index][segment[fresh]], radius)

    def _stamp(self, rows: np.ndarray, cols: np.ndarray, colors: np.ndarray, radius_px: float) -> None:
        """Paint the footprint of ``radius_px`` around each pixel ``(rows[i], cols[i])``, clipped to the image."""
        drow, dcol = _footprint(float(radius_px))
        r = (rows[:, None] + drow[None, :]).ravel()
        c = (cols[:, None] + dcol[None, :]).ravel()
        inside = (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)
        if colors.ndim == 1:
            self._image[r[inside], c[inside]] = colors
        else:
            self._image[r[inside], c[inside]] = np.repeat(colors, len(drow), axis=0)[inside]

    def _fill_polygon(self, px: np.ndarray, fill: np.ndarray) -> None:
        """Fill a pixel-space polygon by the even-odd rule over its clipped bounding box only."""
        c0, c1 = max(math.floor(px[:, 0].min()), 0), min(math.ceil(px[:, 0].max()), self.width)
        r0, r1 = max(math.floor(px[:, 1].min()), 0), min(math.ceil(px[:, 1].max()), self.height)
        if c0 >= c1 or r0 >= r1:
            return
        xc = np.arange(c0, c1) + 0.5
        yc = np.arange(r0, r1) + 0.5
        inside = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        for (x0, y0), (x1, y1) in zip(px, np.roll(px, -1, axis=0)):
            if y0 == y1:
                continue  # horizontal edges never cross a row of pixel centres under the half-open rule
            # Half-open in y so a vertex shared by two edges is counted once.
            crosses = (y0 <= yc) != (y1 <= yc)
            if not crosses.any():
                continue
            x_at = x0 + (yc[crosses] - y0) * ((x1 - x0) / (y1 - y0))
            inside[crosses] ^= xc[None, :] < x_at[:, None]
        self._image[r0:r1, c0:c1][inside] = fill
