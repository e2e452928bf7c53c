"""Occupancy mapping from range readings, from either the true or the dead-reckoned pose (paper, Figure 8).

The paper replays the actuator sequence without noise to place the sensed obstacle points and compares them with
the true positions: the map degrades with distance travelled. :class:`OccupancyGrid` turns readings into a grid
from whichever pose it is given, so both maps can be built side by side and compared.
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
from polyenvs.core.jit import njit

__all__ = ["OccupancyGrid", "mark_beams", "obstacle_points", "placement_error", "placement_gaps"]

_COS_ELEVATION = float(np.cos(SENSOR_ELEVATION_RAD))
_MAX_BEAM_CM = RANGE_MAX_CM * _COS_ELEVATION  # horizontal reach of a beam from its sensor


def obstacle_points(position: np.ndarray, heading: float, reading: np.ndarray) -> np.ndarray:
    """World points where the six beams hit something, from a pose (``nan`` rows for invalid readings)."""
    az = heading + SENSOR_AZIMUTHS_RAD
    r = horizontal_range(reading)
    return position + r[:, None] * np.stack([np.cos(az), np.sin(az)], axis=-1)


def placement_error(true_pose, dead_reckoned_pose, reading) -> tuple[float, int]:
    """How far the obstacle points of one set of readings move when placed from the dead-reckoned pose instead
    of the true one (the paper's Figure 8): ``(sum of distances in cm, number of valid readings)``.

    Poses are ``(x, y, heading_rad)``.
    """
    return placement_gaps(
        *(float(v) for v in true_pose), *(float(v) for v in dead_reckoned_pose), np.asarray(reading, dtype=np.float64)
    )


# Module-level arrays are frozen into the compiled code.
_SENSOR_COS, _SENSOR_SIN = np.cos(SENSOR_AZIMUTHS_RAD), np.sin(SENSOR_AZIMUTHS_RAD)


@njit(cache=True)
def placement_gaps(xt, yt, ht, xd, yd, hd, reading):
    """Compiled core of :func:`placement_error` for one pose pair."""
    ca, sa = _SENSOR_COS, _SENSOR_SIN
    cht, sht, chd, shd = math.cos(ht), math.sin(ht), math.cos(hd), math.sin(hd)  # rotate, don't re-evaluate trig
    total, count = 0.0, 0
    for i in range(reading.shape[0]):
        if math.isnan(reading[i]):
            continue
        r = (reading[i] + HEXAGON_INRADIUS_CM) * _COS_ELEVATION  # horizontal distance from the centre
        dx = xt - xd + r * ((cht * ca[i] - sht * sa[i]) - (chd * ca[i] - shd * sa[i]))
        dy = yt - yd + r * ((sht * ca[i] + cht * sa[i]) - (shd * ca[i] + chd * sa[i]))
        total += math.hypot(dx, dy)
        count += 1
    return total, count


class OccupancyGrid:
    """Cells seen by the beams (0 = unknown, 1 = free, 2 = occupied) on a regular grid.

    Args:
        origin: world coordinates (cm) of the lower-left corner of cell (0, 0).
        shape: (rows, cols).
        cell_cm: cell size.
    """

    UNKNOWN, FREE, OCCUPIED = 0, 1, 2

    def __init__(self, origin, shape: tuple[int, int], cell_cm: float = 10.0, cells: np.ndarray | None = None):
        self.origin = np.asarray(origin, dtype=np.float64)
        self.cell_cm = float(cell_cm)
        self.cells = np.zeros(shape, dtype=np.int8) if cells is None else cells  # ``cells``: share a buffer
        self._everywhere = np.ones(shape, dtype=np.bool_)

    def observe(self, position, heading: float, reading, too_close, no_return, count_in=None) -> int:
        """Mark the six beams of one set of readings from a pose; returns how many cells turned from unknown to free
        (only those where ``count_in`` is true, if given).

        A beam with a valid reading frees the cells up to its hit and marks the hit occupied; a beam with no return
        frees its whole reach; a sensor that did not settle (too close) tells nothing about where.
        """
        x, y = (float(v) for v in position)
        return mark_beams(
            self.cells, self.origin[0], self.origin[1], self.cell_cm, x, y, float(heading),
            np.asarray(reading, dtype=np.float64), np.asarray(too_close), np.asarray(no_return),
            self._everywhere if count_in is None else count_in,
        )  # fmt: skip


@njit(cache=True)
def mark_beams(cells, ox, oy, cell, x, y, heading, reading, too_close, no_return, count_in):
    """Compiled core of :meth:`OccupancyGrid.observe` on one grid; returns the cells newly freed in ``count_in``."""
    ca, sa, sensor_offset = _SENSOR_COS, _SENSOR_SIN, SENSOR_HORIZONTAL_OFFSET_CM
    cos_elevation, max_beam = _COS_ELEVATION, _MAX_BEAM_CM
    rows, cols = cells.shape
    step = 0.5 * cell  # sample each beam at half a cell so no crossed cell is skipped
    ch, sh = math.cos(heading), math.sin(heading)
    fresh = 0
    for i in range(6):
        if too_close[i]:
            continue
        dx, dy = ch * ca[i] - sh * sa[i], sh * ca[i] + ch * sa[i]
        sx, sy = x + sensor_offset * dx, y + sensor_offset * dy
        length = max_beam if no_return[i] else reading[i] * cos_elevation
        # Stop the free part half a cell short of the hit so the wall's own cell is not called free.
        free_length = length if no_return[i] else max(length - 0.5 * cell, 0.0)
        n = int(free_length / step) + 1
        for k in range(n + 1):
            t = min(k * step, free_length)
            col = int(math.floor((sx + t * dx - ox) / cell))
            row = int(math.floor((sy + t * dy - oy) / cell))
            if 0 <= row < rows and 0 <= col < cols and cells[row, col] == 0:
                cells[row, col] = 1
                if count_in[row, col]:
                    fresh += 1
        if not no_return[i]:
            col = int(math.floor((sx + length * dx - ox) / cell))
            row = int(math.floor((sy + length * dy - oy) / cell))
            if 0 <= row < rows and 0 <= col < cols:
                cells[row, col] = 2
    return fresh
