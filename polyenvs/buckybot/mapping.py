"""Occupancy mapping from range readings, from either the true or the dead-reckoned pose (paper, Figure 8).

The paper replays the actuator sequence without noise to place the sensed obstacle points and compares them with
the true positions: the map degrades with distance travelled. :class:`OccupancyGrid` turns readings into a grid
from whichever pose it is given, so both maps can be built side by side and compared.
"""

from __future__ import annotations

import numpy as np

from polyenvs.buckybot.geometry import SENSOR_AZIMUTHS_RAD, SENSOR_ELEVATION_RAD, SENSOR_HORIZONTAL_OFFSET_CM
from polyenvs.buckybot.sensors import RANGE_MAX_CM, horizontal_range

__all__ = ["OccupancyGrid", "obstacle_points"]

_COS_ELEVATION = float(np.cos(SENSOR_ELEVATION_RAD))
_MAX_BEAM_CM = RANGE_MAX_CM * _COS_ELEVATION  # horizontal reach of a beam from its sensor


def obstacle_points(position: np.ndarray, heading: float, reading: np.ndarray) -> np.ndarray:
    """World points where the six beams hit something, from a pose (``nan`` rows for invalid readings)."""
    az = heading + SENSOR_AZIMUTHS_RAD
    r = horizontal_range(reading)
    return position + r[:, None] * np.stack([np.cos(az), np.sin(az)], axis=-1)


class OccupancyGrid:
    """Cells seen free by a beam (0 = unknown, 1 = free, 2 = occupied) on a regular grid.

    Args:
        origin: world coordinates (cm) of the lower-left corner of cell (0, 0).
        shape: (rows, cols).
        cell_cm: cell size.
    """

    UNKNOWN, FREE, OCCUPIED = 0, 1, 2

    def __init__(self, origin, shape: tuple[int, int], cell_cm: float = 10.0):
        self.origin = np.asarray(origin, dtype=np.float64)
        self.cell_cm = float(cell_cm)
        self.cells = np.zeros(shape, dtype=np.int8)
        n_samples = int(np.ceil(_MAX_BEAM_CM / (0.5 * self.cell_cm))) + 1
        self._fractions = np.linspace(0.0, 1.0, n_samples)

    def observe(self, position, heading: float, reading, too_close, no_return) -> np.ndarray:
        """Mark the beams of one set of readings; returns the flat indices of the cells seen free.

        A beam with a valid reading frees the cells up to its hit and marks the hit occupied; a beam with no return
        frees its whole reach; a sensor that did not settle (too close) tells nothing about where.
        """
        az = heading + SENSOR_AZIMUTHS_RAD
        direction = np.stack([np.cos(az), np.sin(az)], axis=-1)  # (6, 2)
        origin = np.asarray(position) + SENSOR_HORIZONTAL_OFFSET_CM * direction
        length = np.where(no_return, _MAX_BEAM_CM, np.where(too_close, 0.0, np.nan_to_num(reading) * _COS_ELEVATION))
        # Stop the free part half a cell short of the hit so the wall's own cell is not called free.
        free_len = np.maximum(length - np.where(no_return, 0.0, 0.5 * self.cell_cm), 0.0)
        samples = origin[:, None, :] + (free_len[:, None] * self._fractions)[..., None] * direction[:, None, :]
        free_idx = self._flat_index(samples[free_len > 0].reshape(-1, 2))
        self.cells.flat[free_idx] = np.maximum(self.cells.flat[free_idx], self.FREE)
        valid = ~(too_close | no_return)
        if valid.any():
            hits = origin[valid] + length[valid, None] * direction[valid]
            self.cells.flat[self._flat_index(hits)] = self.OCCUPIED
        return free_idx

    def _flat_index(self, points: np.ndarray) -> np.ndarray:
        idx = np.floor((points - self.origin) / self.cell_cm).astype(np.int64)
        rows, cols = self.cells.shape
        inside = (idx[:, 0] >= 0) & (idx[:, 0] < cols) & (idx[:, 1] >= 0) & (idx[:, 1] < rows)
        idx = idx[inside]
        return idx[:, 1] * cols + idx[:, 0]
