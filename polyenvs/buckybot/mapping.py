"""Occupancy mapping from range readings, from either the true or the dead-reckoned pose (paper, Figure 8).

The paper replays the actuator sequence without noise to place the sensed obstacle points and compares them with
the true positions: the map degrades with distance travelled. :class:`OccupancyGrid` turns readings into a grid
from whichever pose it is given, so both maps can be built side by side and compared
(:func:`polyenvs.buckybot.analysis.figure8_maps` does it for an exploration run).

Geometry of a beam: the sensor sits at the centre of an upper hexagon, 11.95 cm from the body centre along the
face normal, which points 19.47° above the horizon at azimuth ``heading + SENSOR_AZIMUTHS_RAD[i]``. A slant reading
``r`` therefore puts the hit ``r cos 19.47°`` horizontally beyond the sensor, ``(r + 11.95) cos 19.47°`` from the
centre (:func:`polyenvs.buckybot.sensors.horizontal_range`).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot.geometry import (
    HEXAGON_INRADIUS_CM,
    SENSOR_AZIMUTHS_RAD,
    SENSOR_ELEVATION_RAD,
    SENSOR_HORIZONTAL_OFFSET_CM,
)
from polyenvs.buckybot.sensors import RANGE_MAX_CM, horizontal_range
from polyenvs.core import libm
from polyenvs.core.jit import njit

__all__ = ["OccupancyGrid", "known_bits", "mark_beams", "obstacle_points", "placement_error", "placement_gaps"]

_COS_ELEVATION = float(libm.cos(SENSOR_ELEVATION_RAD))
_MAX_BEAM_CM = RANGE_MAX_CM * _COS_ELEVATION  # horizontal reach of a beam from its sensor


def obstacle_points(position: np.ndarray, heading: float, reading: np.ndarray) -> np.ndarray:
    """World points where the six beams hit something, from a pose (``nan`` rows for invalid readings).

    Args:
        position: ``(x, y)`` of the body centre (cm).
        heading: world azimuth of the motion frame's direction 0 (rad).
        reading: the six slant readings (cm, ``nan`` where invalid).
    """
    az = heading + SENSOR_AZIMUTHS_RAD
    r = horizontal_range(np.asarray(reading, dtype=np.float64))
    return np.asarray(position, dtype=np.float64) + r[:, None] * np.stack([libm.cos(az), libm.sin(az)], axis=-1)


def placement_error(true_pose, dead_reckoned_pose, reading) -> tuple[float, int]:
    """How far the obstacle points of one set of readings move when placed from the dead-reckoned pose instead
    of the true one (the paper's Figure 8): ``(sum of distances in cm, number of valid readings)``.

    Poses are ``(x_cm, y_cm, heading_rad)``.
    """
    return placement_gaps(
        tuple(float(v) for v in true_pose),
        tuple(float(v) for v in dead_reckoned_pose),
        np.asarray(reading, dtype=np.float64),
    )


# Module-level arrays are frozen into the compiled code.
_SENSOR_COS, _SENSOR_SIN = libm.cos(SENSOR_AZIMUTHS_RAD), libm.sin(SENSOR_AZIMUTHS_RAD)


@njit(cache=True)
def placement_gaps(true_pose, dead_reckoned_pose, reading):
    """Compiled core of :func:`placement_error` for one pose pair, each ``(x, y, heading)``."""
    xt, yt, ht = true_pose
    xd, yd, hd = dead_reckoned_pose
    return placement_gaps_rotated((xt, yt, math.cos(ht), math.sin(ht)), (xd, yd, math.cos(hd), math.sin(hd)), reading)


@njit(cache=True)
def placement_gaps_rotated(true_pose, dead_reckoned_pose, reading):
    """:func:`placement_gaps` with each heading given by its cosine and sine, poses ``(x, y, cos, sin)`` (a
    simulator that keeps them)."""
    xt, yt, cht, sht = true_pose
    xd, yd, chd, shd = dead_reckoned_pose
    ca, sa = _SENSOR_COS, _SENSOR_SIN
    total, count = 0.0, 0
    for i in range(reading.shape[0]):
        if math.isnan(reading[i]):
            continue
        r = (reading[i] + HEXAGON_INRADIUS_CM) * _COS_ELEVATION  # horizontal distance from the centre
        dx = xt - xd + r * ((cht * ca[i] - sht * sa[i]) - (chd * ca[i] - shd * sa[i]))
        dy = yt - yd + r * ((sht * ca[i] + cht * sa[i]) - (shd * ca[i] + chd * sa[i]))
        total += math.sqrt(dx * dx + dy * dy)
        count += 1
    return total, count


class OccupancyGrid:
    """Cells seen by the beams (0 = unknown, 1 = free, 2 = occupied) on a regular grid.

    Cell ``(row, col)`` covers ``[ox + col c, ox + (col + 1) c) x [oy + row c, oy + (row + 1) c)``.

    Args:
        origin: world coordinates (cm) of the lower-left corner of cell (0, 0).
        shape: (rows, cols).
        cell_cm: cell size.
        cells: an existing ``int8`` buffer of ``shape`` to mark into (shared, not copied).
    """

    UNKNOWN, FREE, OCCUPIED = 0, 1, 2

    def __init__(self, origin, shape: tuple[int, int], cell_cm: float = 10.0, cells: np.ndarray | None = None):
        self.origin = np.asarray(origin, dtype=np.float64)
        self.cell_cm = float(cell_cm)
        self.cells = np.zeros(shape, dtype=np.int8) if cells is None else cells  # ``cells``: share a buffer
        self._everywhere = np.ones(shape, dtype=np.bool_)

    @property
    def shape(self) -> tuple[int, int]:
        return self.cells.shape

    def centres(self) -> np.ndarray:
        """``(rows, cols, 2)`` world coordinates of the cell centres."""
        rows, cols = self.shape
        ys, xs = np.mgrid[0:rows, 0:cols]
        return self.origin + (np.stack([xs, ys], axis=-1) + 0.5) * self.cell_cm

    def observe(self, position, heading: float, reading, too_close, no_return, count_in=None) -> int:
        """Mark the six beams of one set of readings from a pose; returns how many cells turned from unknown to free
        (only those where ``count_in`` is true, if given).

        A beam with a valid reading frees the cells up to half a cell short of its hit and marks the hit's cell
        occupied; a beam with no return frees its whole reach (182.88 cm slant); a sensor that did not settle (too
        close) tells nothing about where. ``heading`` is the world azimuth of the frame's direction 0 (rad);
        ``reading`` the slant readings in cm. Cells already occupied stay occupied.
        """
        x, y = (float(v) for v in position)
        beams = (np.asarray(reading, dtype=np.float64), np.asarray(too_close, dtype=np.bool_),
                 np.asarray(no_return, dtype=np.bool_))  # fmt: skip
        frame = (float(self.origin[0]), float(self.origin[1]), self.cell_cm)
        return mark_beams(
            self.cells, frame, (x, y, float(heading)), beams, self._everywhere if count_in is None else count_in
        )


@njit(cache=True)
def _clip_axis(g, d, inv, n, t0, t1):
    """The part ``[t0, t1]`` of the beam ``g + t d`` (one axis, cell units) inside ``[0, n)``; empty if t0 > t1."""
    if d == 0.0:
        return (t0, t1) if 0.0 <= g < n else (1.0, 0.0)
    ta, tb = -g * inv, (n - g) * inv
    return max(t0, min(ta, tb)), min(t1, max(ta, tb))


@njit(cache=True)
def _axis_step(cell, p, d, inv):
    """Along one axis: the cell step, the distance along the beam to the next cell boundary, and between two."""
    if d > 0.0:
        return 1, (cell + 1 - p) * inv, inv
    if d < 0.0:
        return -1, (cell - p) * inv, -inv
    return 0, math.inf, math.inf


#: How far (cell units) the cells a walk may visit can lie from its exact segment, with room to spare: rounding in
#: the walk's summed crossing distances moves it by about 1e-12 at a grid corner or at the segment's end.
_WALK_SLACK = 1e-6
#: Beyond this (cell units) a segment's ends are left to the walk, which clips first, so no conversion overflows.
_FAR = 1e5
_ONE, _SIXTY_THREE, _ALL = np.uint64(1), np.uint64(63), np.uint64(0xFFFFFFFFFFFFFFFF)


@njit(cache=True)
def known_bits(cells):
    """Bit planes of a grid for :func:`mark_beams_rotated`, ``uint64`` words of packed bits (a beam's few lines of
    cells then share a cache line or two): ``known_rows``, the known cells (``cells != 0``) row by row and then the
    occupied ones, and ``known_cols``, the known cells column by column."""
    rows, cols = cells.shape
    words = (rows * cols + 63) // 64
    known_rows = np.zeros(2 * words, dtype=np.uint64)
    known_cols = np.zeros(words, dtype=np.uint64)
    for r in range(rows):
        for c in range(cols):
            if cells[r, c] != 0:
                _set_known(known_rows, known_cols, rows, cols, r, c)
            if cells[r, c] == 2:
                _set_occupied(known_rows, cols, r, c)
    return known_rows, known_cols


@njit(cache=True)
def _set_known(known_rows, known_cols, rows, cols, r, c):
    i, j = r * cols + c, c * rows + r
    known_rows[i >> 6] |= _ONE << np.uint64(i & 63)
    known_cols[j >> 6] |= _ONE << np.uint64(j & 63)


@njit(cache=True)
def _set_occupied(known_rows, cols, r, c):
    i = r * cols + c
    known_rows[known_rows.shape[0] // 2 + (i >> 6)] |= _ONE << np.uint64(i & 63)


@njit(cache=True)
def _is_occupied(known_rows, cols, r, c):
    i = r * cols + c
    return known_rows[known_rows.shape[0] // 2 + (i >> 6)] >> np.uint64(i & 63) & _ONE != 0


@njit(cache=True)
def _span_known(bits, lo, hi):
    """Whether bits ``lo..hi`` (inclusive) are all set, up to 64 at a time."""
    while True:
        w, shift = lo >> 6, np.uint64(lo & 63)
        width = min(hi - lo, 63) + 1
        word = bits[w] >> shift
        if (lo & 63) + width > 64:  # the span runs on into the next word
            word |= (bits[w + 1] << _ONE) << (_SIXTY_THREE - shift)
        mask = _ALL >> np.uint64(64 - width)
        if word & mask != mask:
            return False
        if hi - lo < 64:
            return True
        lo += 64


@njit(cache=True)
def _beam_settled(planes, segment, direction):
    """Whether the walk along ``segment = (gx, gy, qx, qy)`` (cell units, unit ``direction = (dx, dy)``) over the
    grid ``planes = (cells, known_rows, known_cols)`` would find every cell it crosses known: whether every cell
    within ``_WALK_SLACK`` of it is, by lines of cells along whichever axis the segment crosses fewer lines of. A
    segment far off the grid is left to the walk, which clips first."""
    cells, known_rows, known_cols = planes
    rows, cols = cells.shape
    gx, gy, qx, qy = segment
    dx, dy = direction
    if not (abs(gx) < _FAR and abs(gy) < _FAR and abs(qx) < _FAR and abs(qy) < _FAR):
        return False
    if abs(dx) >= abs(dy):
        return _near_cells_known(known_rows, rows, cols, gy, qy, gx, qx)
    return _near_cells_known(known_cols, cols, rows, gx, qx, gy, qy)


@njit(cache=True)
def _near_cells_known(bits, lines, length, a0, a1, b0, b1):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Whether every cell within ``_WALK_SLACK`` of the segment ``(a0, b0)``-``(a1, b1)`` is known, the cells taken
    as ``lines`` lines of ``length`` cells along the ``b`` axis (line ``k``: bits ``k length`` on); parts off the
    grid need nothing.

    Truncation stands for the floor throughout: it differs only below zero, where it adds a cell, never drops one.
    """
    if a1 < a0:  # walk the lines upwards
        a0, a1, b0, b1 = a1, a0, b1, b0
    first = int(max(a0 - _WALK_SLACK, 0.0))
    last = int(min(a1 + _WALK_SLACK, lines - 1.0))
    if a1 - a0 <= _WALK_SLACK:  # along a line: its whole extent, in one or two lines
        c0 = int(max(min(b0, b1) - _WALK_SLACK, 0.0))
        c1 = int(min(max(b0, b1) + _WALK_SLACK, length - 1.0))
        for line in range(first, last + 1):
            if c0 <= c1 and not _span_known(bits, line * length + c0, line * length + c1):
                return False
        return True
    slope = (b1 - b0) / (a1 - a0)
    # The slack across the lines moves the segment by |slope| times as much along them.
    slack = _WALK_SLACK * (1.0 + abs(slope))
    enter = b0 + (max(float(first), a0) - a0) * slope
    for line in range(first, last + 1):
        leave = b0 + (min(line + 1.0, a1) - a0) * slope
        c0 = int(max(min(enter, leave) - slack, 0.0))
        c1 = int(min(max(enter, leave) + slack, length - 1.0))
        if c0 <= c1 and not _span_known(bits, line * length + c0, line * length + c1):
            return False
        enter = leave
    return True


@njit(cache=True)
def _free_cells(planes, count_in, start, direction, length):
    """Free the unknown cells of ``planes = (cells, known_rows, known_cols)`` crossed by the segment from grid
    point ``start = (gx, gy)`` (cell units) along the unit ``direction = (dx, dy)`` for ``length`` cells, each
    crossed cell visited once (Amanatides & Woo's traversal), keeping the bit planes up to date.

    The segment is first clipped to the grid, so a beam from a pose far outside costs nothing and every index
    stays in range. Returns the cells newly freed where ``count_in`` is true.
    """
    cells, known_rows, known_cols = planes
    gx, gy = start
    dx, dy = direction
    rows, cols = cells.shape
    inf = math.inf
    # Reciprocals once: the clipping and the traversal below then need no further division.
    ix = inf if dx == 0.0 else 1.0 / dx
    iy = inf if dy == 0.0 else 1.0 / dy
    t0, t1 = _clip_axis(gx, dx, ix, cols, 0.0, length)
    t0, t1 = _clip_axis(gy, dy, iy, rows, t0, t1)
    if not t0 <= t1:  # also false for nan
        return 0
    # Restart from the entry point: every quantity below is then bounded by the grid's size.
    px, py, span = gx + t0 * dx, gy + t0 * dy, t1 - t0
    col, row = int(math.floor(px)), int(math.floor(py))
    step_c, next_c, delta_c = _axis_step(col, px, dx, ix)
    step_r, next_r, delta_r = _axis_step(row, py, dy, iy)
    # The segment crosses exactly this many cell boundaries; counting them, rather than testing the distance
    # travelled at every step, and choosing the axis without a branch make the walk a tight loop.
    end_c = min(max(int(math.floor(px + span * dx)), 0), cols - 1)
    end_r = min(max(int(math.floor(py + span * dy)), 0), rows - 1)
    fresh = 0
    for _ in range(abs(end_c - col) + abs(end_r - row) + 1):
        if 0 <= row < rows and 0 <= col < cols and cells[row, col] == 0:
            cells[row, col] = 1
            _set_known(known_rows, known_cols, rows, cols, row, col)
            if count_in[row, col]:
                fresh += 1
        across = next_c < next_r
        col += step_c if across else 0
        row += 0 if across else step_r
        next_c += delta_c if across else 0.0
        next_r += 0.0 if across else delta_r
    return fresh


@njit(cache=True)
def mark_beams(cells, frame, pose, beams, count_in):
    """Compiled core of :meth:`OccupancyGrid.observe` on one grid; returns the cells newly freed in ``count_in``.

    ``frame = (ox, oy, cell)``: the grid's origin and cell size (cm); ``pose = (x, y, heading)``; ``beams =
    (reading, too_close, no_return)``, the six readings and their flags.
    """
    x, y, heading = pose
    if not math.isfinite(heading):
        return 0
    known_rows, known_cols = known_bits(cells)
    return mark_beams_rotated(
        (cells, known_rows, known_cols), frame, (x, y, math.cos(heading), math.sin(heading)), beams, count_in
    )


@njit(cache=True)
def mark_beams_rotated(planes, frame, pose, beams, count_in):
    """:func:`mark_beams` on the grid and its bit planes ``planes = (cells, known_rows, known_cols)``
    (:func:`known_bits`), which it keeps up to date with ``cells``, from ``pose = (x, y, cos, sin)``, the heading
    given by its cosine and sine (a simulator that keeps them).

    Each beam frees the cells its segment crosses (:func:`_free_cells`). Most beams cross only known cells: the
    bit planes settle that a line of cells at a time (:func:`_beam_settled`), and the walk runs only where some
    cell near the segment is unknown, so the cells marked are exactly those the walk alone would mark.
    """
    cells, known_rows, known_cols = planes
    ox, oy, cell = frame
    x, y, ch, sh = pose
    reading, too_close, no_return = beams
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(ch) and math.isfinite(sh)):
        return 0
    ca, sa, sensor_offset = _SENSOR_COS, _SENSOR_SIN, SENSOR_HORIZONTAL_OFFSET_CM
    rows, cols = cells.shape
    inv_cell = 1.0 / cell
    fresh = 0
    for i in range(6):
        if too_close[i]:
            continue
        dx, dy = ch * ca[i] - sh * sa[i], sh * ca[i] + ch * sa[i]
        sx, sy = x + sensor_offset * dx, y + sensor_offset * dy
        # The beam climbs at 19.47°: a slant reading covers only its cosine horizontally.
        length = _MAX_BEAM_CM if no_return[i] else reading[i] * _COS_ELEVATION
        if not (length >= 0.0 and math.isfinite(length)):
            continue
        # Stop the free part half a cell short of the hit so the wall's own cell is not called free.
        free_length = length if no_return[i] else max(length - 0.5 * cell, 0.0)
        gx, gy = (sx - ox) * inv_cell, (sy - oy) * inv_cell
        reach = free_length * inv_cell
        qx, qy = gx + reach * dx, gy + reach * dy
        if not _beam_settled(planes, (gx, gy, qx, qy), (dx, dy)):
            fresh += _free_cells(planes, count_in, (gx, gy), (dx, dy), reach)
        if not no_return[i]:
            # Compare as floats before converting: a far-off hit must not overflow the integer cast.
            hc, hr = gx + length * inv_cell * dx, gy + length * inv_cell * dy
            if 0.0 <= hc < cols and 0.0 <= hr < rows:
                r, c = int(hr), int(hc)
                if not _is_occupied(known_rows, cols, r, c):  # else the cell holds 2 already
                    if cells[r, c] == 0:
                        _set_known(known_rows, known_cols, rows, cols, r, c)
                    _set_occupied(known_rows, cols, r, c)
                    cells[r, c] = 2
    return fresh
