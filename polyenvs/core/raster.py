"""A tiny numpy rasterizer for top-down RGB frames of planar robots.

``Canvas`` maps a world rectangle (y up) onto an ``(H, W, 3)`` uint8 image (row 0 at the top) and draws the few
primitives a planar scene needs: segments (walls, beams), polylines (paths), filled polygons (robot bodies), discs
and point markers. There is no anti-aliasing. Every primitive is drawn with a constant number of numpy calls
whatever the number of points, so a typical 480x480 frame takes a few milliseconds.

Pixel convention: :meth:`Canvas.to_pixels` returns continuous ``(col, row)`` coordinates in which pixel ``(c, r)``
covers ``[c, c + 1) x [r, r + 1)``; its centre is ``(c + 0.5, r + 0.5)``. Area fills (polygons, discs) test pixel
centres; strokes (lines, markers) paint the pixel each sample falls in, plus a disc-shaped footprint of neighbours.

Everything clips silently to the image, non-finite points (and points so far away that their pixel coordinates
overflow) are skipped, and empty inputs draw nothing.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from polyenvs.core.validation import check_finite, check_positive

__all__ = [
    "DEAD_RECKONED_PATH",
    "FRAME_WIDTH_PX",
    "TRUE_PATH",
    "WALL",
    "Canvas",
    "stamp_text",
    "text_width",
    "with_legend",
]

#: The house style every family's frames share: their width and the colours of what means the same in each.
FRAME_WIDTH_PX = 480
WALL = (30, 30, 30)
TRUE_PATH = (200, 40, 40)
DEAD_RECKONED_PATH = (60, 90, 220)

# Hidden border around the frame: stroke footprints that spill over an edge land there instead of being
# bounds-checked pixel by pixel. Grown on demand for very wide strokes.
_INITIAL_BORDER_PX = 8


@lru_cache(maxsize=32)
def _glyph(*rows: str) -> np.ndarray:
    return np.array([[c == "#" for c in row] for row in rows], dtype=bool)


# A 3x5 pixel font: digits, capitals (lower case is drawn in capitals) and the punctuation labels need.
_FONT_ROWS = {
    "A": ".#.|#.#|###|#.#|#.#", "B": "##.|#.#|##.|#.#|##.", "C": ".##|#..|#..|#..|.##", "D": "##.|#.#|#.#|#.#|##.",
    "E": "###|#..|##.|#..|###", "F": "###|#..|##.|#..|#..", "G": ".##|#..|#.#|#.#|.##", "H": "#.#|#.#|###|#.#|#.#",
    "I": "###|.#.|.#.|.#.|###", "J": "..#|..#|..#|#.#|.#.", "K": "#.#|#.#|##.|#.#|#.#", "L": "#..|#..|#..|#..|###",
    "M": "#.#|###|###|#.#|#.#", "N": "##.|#.#|#.#|#.#|#.#", "O": ".#.|#.#|#.#|#.#|.#.", "P": "##.|#.#|##.|#..|#..",
    "Q": ".#.|#.#|#.#|##.|.##", "R": "##.|#.#|##.|#.#|#.#", "S": ".##|#..|.#.|..#|##.", "T": "###|.#.|.#.|.#.|.#.",
    "U": "#.#|#.#|#.#|#.#|###", "V": "#.#|#.#|#.#|#.#|.#.", "W": "#.#|#.#|###|###|#.#", "X": "#.#|#.#|.#.|#.#|#.#",
    "Y": "#.#|#.#|.#.|.#.|.#.", "Z": "###|..#|.#.|#..|###", "0": "###|#.#|#.#|#.#|###", "1": ".#.|##.|.#.|.#.|###",
    "2": "###|..#|###|#..|###", "3": "###|..#|###|..#|###", "4": "#.#|#.#|###|..#|..#", "5": "###|#..|###|..#|###",
    "6": "###|#..|###|#.#|###", "7": "###|..#|..#|..#|..#", "8": "###|#.#|###|#.#|###", "9": "###|#.#|###|..#|###",
    "_": "...|...|...|...|###", "-": "...|...|###|...|...", ".": "...|...|...|...|.#.", "/": "..#|..#|.#.|#..|#..",
    "[": "##.|#..|#..|#..|##.", "]": ".##|..#|..#|..#|.##", "(": ".#.|#..|#..|#..|.#.", ")": ".#.|..#|..#|..#|.#.",
    ",": "...|...|...|.#.|#..", ":": "...|.#.|...|.#.|...", "%": "#.#|..#|.#.|#..|#.#", "=": "...|###|...|###|...",
    "+": "...|.#.|###|.#.|...", "'": ".#.|.#.|...|...|...", " ": "...|...|...|...|...",
}  # fmt: skip
_GLYPHS = {ch: _glyph(*rows.split("|")) for ch, rows in _FONT_ROWS.items()}


def text_width(text: str, scale: int) -> int:
    """Width in pixels of ``text`` in the 3x5 font at ``scale`` pixels per dot (one dot between characters)."""
    return max(0, 4 * scale * len(text) - scale)


def stamp_text(image: np.ndarray, left: int, top: int, text: str, color, scale: int = 2) -> None:
    """Write ``text`` into an ``(H, W, 3)`` image with its top-left corner at pixel (``left``, ``top``), clipped to
    the image; characters the font lacks are drawn as spaces."""
    height, width, _ = image.shape
    x = left
    for ch in str(text).upper():
        rows, cols = np.nonzero(np.kron(_GLYPHS.get(ch, _GLYPHS[" "]), np.ones((scale, scale), dtype=bool)))
        rows, cols = rows + top, cols + x
        keep = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
        image[rows[keep], cols[keep]] = color
        x += 4 * scale


def _footprint(radius_px: float) -> tuple[np.ndarray, np.ndarray]:
    """``(drow, dcol)`` offsets of the pixels whose centres lie within ``radius_px`` of a pixel centre."""
    reach = math.floor(radius_px)
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


def _as_colors(name: str, color, count: int | None = None) -> np.ndarray:
    """One RGB triple ``(3,)``, or (if ``count`` is given) one per item ``(count, 3)``, as uint8 in 0..255."""
    c = np.asarray(color, dtype=np.float64)
    if c.shape != (3,) and (count is None or c.shape != (count, 3)):
        expected = "an RGB triple" if count is None else f"an RGB triple or have shape ({count}, 3)"
        raise ValueError(f"{name} must be {expected}, got shape {c.shape}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} must be finite")
    return np.clip(np.rint(c), 0, 255).astype(np.uint8)


def _clip_segments(a: np.ndarray, b: np.ndarray, low: np.ndarray, high: np.ndarray):
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
        start, end = a + t0[:, None] * d, a + t1[:, None] * d
    # Ends near the float limit overflow (inf - inf); such segments are dropped rather than drawn wrongly.
    keep &= (t0 <= t1) & np.isfinite(start).all(axis=1) & np.isfinite(end).all(axis=1)
    return start, end, keep


class Canvas:
    """An RGB image mapped onto a world rectangle (world units, y up; image row 0 at the top).

    Args:
        bounds: ``(xmin, ymin, xmax, ymax)`` of the region to show, in world units.
        width: image width in pixels; the height follows from the aspect ratio of the (margined) bounds.
        margin: fraction of the larger side of ``bounds`` added on every side.
        background: RGB fill of the initial image.
    """

    def __init__(
        self,
        bounds: tuple[float, float, float, float],
        width: int = 480,
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
        self.height = max(1, round(self.width * span_y / span_x))
        self.scale = min(self.width / span_x, self.height / span_y)  # pixels per world unit
        self._centre = (0.5 * (xmin + xmax), 0.5 * (ymin + ymax))
        self.bounds = (xmin, ymin, xmax, ymax)
        self._background = _as_colors("background", background)
        self._border = -1
        self._reserve_border(_INITIAL_BORDER_PX)

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
        with np.errstate(over="ignore"):  # absurdly far points become inf, which every primitive skips
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
        colors = _as_colors("color", color)
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
        fill = _as_colors("color", color)
        edge = None if outline is None else _as_colors("outline", outline)
        px = self.to_pixels(v)
        px = px[np.isfinite(px).all(axis=1)]
        if len(px) == 0:
            return
        if len(px) >= 3:
            self._fill_polygon(px, fill)
        if edge is not None:
            self._stroke(px, np.roll(px, -1, axis=0), edge, 1.0)

    def disc(self, centre, radius, color) -> None:
        """Fill the disc of world ``radius`` around world ``centre``; at least the centre's pixel is painted."""
        c = np.asarray(centre, dtype=np.float64)
        if c.shape != (2,):
            raise ValueError(f"centre must have shape (2,), got {c.shape}")
        radius = check_positive("radius", radius, allow_zero=True)
        fill = _as_colors("color", color)
        cx, cy = (float(v) for v in self.to_pixels(c))
        r = radius * self.scale
        if not (math.isfinite(cx) and math.isfinite(cy) and math.isfinite(r)):
            return
        c0, c1 = max(math.floor(cx - r), 0), min(math.floor(cx + r) + 1, self.width)
        r0, r1 = max(math.floor(cy - r), 0), min(math.floor(cy + r) + 1, self.height)
        if c0 >= c1 or r0 >= r1:
            return
        dx = np.arange(c0, c1) + 0.5 - cx
        dy = np.arange(r0, r1) + 0.5 - cy
        inside = np.hypot(dy[:, None], dx[None, :]) <= r  # hypot, not squares: a huge far-off disc must not overflow
        # Sub-pixel discs would otherwise vanish; the centre pixel is always inside the clipped box if on-screen.
        if c0 <= cx < c1 and r0 <= cy < r1:
            inside[math.floor(cy) - r0, math.floor(cx) - c0] = True
        self._cells[r0:r1, c0:c1][inside] = fill.view("V3")[0]

    def text(self, anchor, label: str, color, scale: int = 2) -> None:
        """Write ``label`` centred on world point ``anchor`` in the 3x5 pixel font, ``scale`` px per dot.

        Enough for labels such as face or robot numbers without a font library; characters the font lacks are
        skipped.
        """
        glyphs = [_GLYPHS[ch] for ch in str(label).upper() if ch in _GLYPHS]
        if not glyphs:
            return
        bitmap = np.concatenate([np.pad(g, ((0, 0), (0, 1))) for g in glyphs], axis=1)[:, :-1]
        bitmap = np.kron(bitmap, np.ones((scale, scale), dtype=bool))
        cx, cy = (float(v) for v in self.to_pixels(np.asarray(anchor, dtype=np.float64)))
        if not (math.isfinite(cx) and math.isfinite(cy)):
            return
        rows, cols = np.nonzero(bitmap)
        rows = rows + math.floor(cy - bitmap.shape[0] / 2)
        cols = cols + math.floor(cx - bitmap.shape[1] / 2)
        keep = (rows >= 0) & (rows < self.height) & (cols >= 0) & (cols < self.width)
        self._cells[rows[keep], cols[keep]] = _as_colors("color", color).view("V3")[0]

    def points(self, points, color, radius_px: float = 1.5) -> None:
        """Draw a round marker of ``radius_px`` pixels at each world point ``(N, 2)``; ``color`` RGB or ``(N, 3)``."""
        p = _as_points("points", points)
        colors = _as_colors("color", color, len(p))
        radius_px = check_positive("radius_px", radius_px, allow_zero=True)
        if len(p) == 0:
            return
        px = self.to_pixels(p)
        reach = math.floor(radius_px) + 1
        self._reserve_border(2 * reach)
        # Markers centred more than their radius off-frame are invisible; dropping them also keeps huge
        # coordinates away from the integer cast.
        on_screen = (px > -reach).all(axis=1) & (px < (self.width + reach, self.height + reach)).all(axis=1)
        index = np.flatnonzero(on_screen)
        cells = np.floor(px[index]).astype(np.intp)
        self._stamp(self._flat_index(cells), colors if colors.ndim == 1 else colors[index], radius_px)

    def _reserve_border(self, border: int) -> None:
        """Make the hidden border at least ``border`` px wide, keeping the frame's contents."""
        if border <= self._border:
            return
        old = self._image if self._border >= 0 else None
        shape = (self.height + 2 * border, self.width + 2 * border, 3)
        buffer = np.empty(shape, dtype=np.uint8)
        # Filling one row and copying it down is far faster than broadcasting a 3-vector over every pixel.
        buffer[0] = self._background
        buffer[1:] = buffer[0]
        self._border = border
        self._stride = shape[1]
        self._image = buffer[border : border + self.height, border : border + self.width]
        if old is not None:
            self._image[...] = old
        # One 3-byte void item per pixel: a masked or fancy-indexed write then moves whole RGB triples, several
        # times faster than broadcasting a colour over the last axis of the (H, W, 3) array.
        self._pixels = buffer.reshape(-1).view("V3")
        self._cells = self._pixels.reshape(shape[:2])[border : border + self.height, border : border + self.width]

    def _flat_index(self, cells: np.ndarray) -> np.ndarray:
        """Index into ``self._pixels`` of integer pixel cells ``(M, 2)`` given as ``(col, row)``."""
        return (cells[:, 1] + self._border) * self._stride + (cells[:, 0] + self._border)

    def _stroke(self, a: np.ndarray, b: np.ndarray, colors: np.ndarray, width_px: float) -> None:
        """Draw pixel-space segments ``a -> b``: DDA-sample them and stamp a round footprint at every sample."""
        radius = 0.5 * width_px
        pad = math.floor(radius) + 1
        self._reserve_border(2 * pad)
        low = np.array([-pad, -pad], dtype=np.float64)
        high = np.array([self.width + pad, self.height + pad], dtype=np.float64)
        # Typically every segment is on-screen and finite (NaN compares False), so clipping is skipped outright.
        within = (np.minimum(a, b) >= low).all(axis=1) & (np.maximum(a, b) <= high).all(axis=1)
        index = None
        if not within.all():
            index = np.flatnonzero(np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1))
            a, b, keep = _clip_segments(a[index], b[index], low, high)
            index, a, b = index[keep], a[keep], b[keep]
            if index.size == 0:
                return
        d = b - a
        # One sample per pixel step along the major axis: consecutive samples are at most one pixel apart on
        # each axis, so the stroke is 8-connected (a Bresenham-like line) with no duplicated work.
        count = np.ceil(np.abs(d).max(axis=1)).astype(np.intp) + 1
        increment = d / np.maximum(count - 1, 1)[:, None]
        first = np.cumsum(count) - count
        step = np.arange(int(count[-1] + first[-1])) - np.repeat(first, count)
        samples = np.repeat(a, count, axis=0) + step[:, None] * np.repeat(increment, count, axis=0)
        flat = self._flat_index(np.floor(samples).astype(np.intp))
        # Connected segments share end pixels; painting them once saves a footprint per joint.
        fresh = np.empty(flat.size, dtype=bool)
        fresh[0] = True
        np.not_equal(flat[1:], flat[:-1], out=fresh[1:])
        if colors.ndim == 1:
            self._stamp(flat[fresh], colors, radius)
        else:
            per_segment = colors if index is None else colors[index]
            self._stamp(flat[fresh], np.repeat(per_segment, count, axis=0)[fresh], radius)

    def _stamp(self, flat: np.ndarray, colors: np.ndarray, radius_px: float) -> None:
        """Paint the footprint of ``radius_px`` around each pixel index ``flat`` (see ``_flat_index``).

        Callers guarantee every footprint pixel lies within the hidden border, so no bounds test is needed.
        """
        drow, dcol = _footprint(float(radius_px))
        offsets = drow * self._stride + dcol
        index = flat if len(offsets) == 1 else (flat[:, None] + offsets[None, :]).ravel()
        if colors.ndim == 1:
            self._pixels[index] = colors.view("V3")[0]
        else:
            self._pixels[index] = np.repeat(np.ascontiguousarray(colors).view("V3").ravel(), len(offsets))

    def _fill_polygon(self, px: np.ndarray, fill: np.ndarray) -> None:
        """Fill a pixel-space polygon by the even-odd rule over its clipped bounding box only.

        A pixel is inside when an odd number of edges cross its row of pixel centres to its right. All edges are
        handled at once: each (edge, row) crossing adds one to a per-row histogram at the first column it does
        not cover, and a right-to-left cumulative sum turns the histogram into per-pixel crossing counts.
        """
        c0, c1 = max(math.floor(px[:, 0].min()), 0), min(math.ceil(px[:, 0].max()), self.width)
        r0, r1 = max(math.floor(px[:, 1].min()), 0), min(math.ceil(px[:, 1].max()), self.height)
        if c0 >= c1 or r0 >= r1:
            return
        h, w = r1 - r0, c1 - c0
        y_centre = np.arange(r0, r1) + 0.5
        start, end = px, np.roll(px, -1, axis=0)
        # Half-open in y, so a vertex shared by two edges counts once and horizontal edges never count.
        edge, row = np.nonzero((start[:, 1, None] <= y_centre) != (end[:, 1, None] <= y_centre))
        if edge.size == 0:
            return
        with np.errstate(over="ignore", invalid="ignore"):
            d = end[edge] - start[edge]
            x_cross = start[edge, 0] + (y_centre[row] - start[edge, 1]) * (d[:, 0] / d[:, 1])
            # Columns c with centre c0 + c + 0.5 < x_cross are 0 .. covered - 1. fmax maps a crossing lost to
            # overflow (NaN, from vertices near the float limit) to 0, i.e. no effect.
            covered = np.fmin(np.fmax(np.ceil(x_cross - c0 - 0.5), 0), w).astype(np.intp)
        histogram = np.bincount(row * (w + 1) + covered, minlength=h * (w + 1)).reshape(h, w + 1)
        # [r, c]: crossings with covered > c, modulo 256 (only the parity matters).
        right_of = np.cumsum(histogram[:, :0:-1], axis=1, dtype=np.uint8)[:, ::-1]
        self._cells[r0:r1, c0:c1][(right_of & 1).view(bool)] = fill.view("V3")[0]


def with_legend(image: np.ndarray, entries, scale: int = 2) -> np.ndarray:
    """``image`` with a key below it: for each ``(label, color)`` a swatch of the colour and its label (the 3x5
    font, capitals), left to right and wrapping, on white. Below, not over the frame, so it hides nothing; the same
    entries give the same height, so an instance's frames keep one size."""
    height, width, _ = image.shape
    pad, swatch, gap, row = 2 * scale, 4 * scale + 2, 2 * scale, 5 * scale + 2 * scale
    spots, x, y = [], pad, pad
    for label, color in entries:
        item = swatch + gap + text_width(str(label), scale) + 3 * gap
        if x > pad and x + item > width:
            x, y = pad, y + row
        spots.append((x, y, str(label), _as_colors("color", color)))
        x += item
    strip = np.full((y + row + pad - 2 * scale, width, 3), 255, dtype=np.uint8)
    strip[0] = 200  # a rule between the frame and its key
    for left, top, label, color in spots:
        strip[top : top + 5 * scale, left : min(left + swatch, width)] = color
        stamp_text(strip, left + swatch + gap, top, label, (40, 40, 40), scale)
    return np.concatenate([image, strip], axis=0)
