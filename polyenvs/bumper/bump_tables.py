"""The bump-space test's answers precomputed on a grid, once per map: what the filter of
:mod:`polyenvs.bumper.bump_space` asks of the map for every particle, read from a table, with the exact geometry
asked only where a cell straddles an answer's boundary. The answers are the exact test's, bit for bit.

The test asks two things of a point: whether the axle is in free space, and whether a bumper point lies deeper
than the tolerance in a wall, within it of a wall, or farther than it from every wall. Both are thresholds on the
point's signed clearance (distance to the nearest wall, negative in a wall: :func:`signed_clearance`), which
changes by at most the distance moved. So a cell whose centre's clearance is more than the cell's half-diagonal
beyond a threshold is on one side of it everywhere, and the cell stores that answer (:data:`AXLE_FREE`,
:data:`AXLE_IN_WALL`; :data:`IN_WALL`, :data:`NEAR`, :data:`CLEAR`); a cell a threshold crosses stores
:data:`UNKNOWN` and its points get the exact test (whose sign, free space or wall, the cell's axle answer still
gives when certain). The cells' radius carries a margin of 1e-6 cm, far more than the rounding of the computed
clearances and cell indices.

One byte per cell, cells of ``cell_cm`` (0.25 cm, coarser where a map would need more than ``max_cells``). Measured
on a busy 2-core machine: the paper's arena, with the margin the bumper reaches past its walls, is 556 x 436 cells
(0.24 MB), built in 1.7 ms; the ``obstacles`` and ``maze`` maps 0.24 and 0.77 MB in 12 and 45 ms; the largest map
accepted (20 m, 256 edges) is capped at 4 MiB (1-cm cells) and takes 0.5-0.8 s, once per map. The build judges blocks of
16 x 16 cells at once where the block's answer is certain, and cell by cell only near the walls.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.bumper.maps import _clearance, free_at
from polyenvs.core.jit import njit

__all__ = [
    "AXLE_FREE",
    "AXLE_IN_WALL",
    "CLEAR",
    "IN_WALL",
    "NEAR",
    "UNKNOWN",
    "BumpSpaceTable",
    "cell_code",
    "point_class",
    "signed_clearance",
]

#: A cell whose answers are not the same over the whole cell (both parts of the code).
UNKNOWN = 0
#: Bits 0-1, a bumper point's class: deeper than the tolerance in a wall, within it of a wall, farther than it.
IN_WALL, NEAR, CLEAR = 1, 2, 3
POINT_BITS = 3
#: Bits 2-3, the axle's: in a wall (or outside the map), in free space.
AXLE_IN_WALL, AXLE_FREE = 4, 8
AXLE_BITS = 12

#: The finest cell and the most cells of one map's table.
CELL_CM = 0.25
MAX_CELLS = 1 << 22
#: The build's blocks: BLOCK x BLOCK cells judged at once where their answer is certain.
_BLOCK = 16
#: Over rounding: the computed clearances and cell indices are off by far less (coordinates stay within 1e6 cm).
_SLACK_CM = 1e-6
# The grid's packed header (the cell counts as floats: a float against an int compares slowly in numba).
_X0, _Y0, _INV_CELL, _CELL, _TOL, _NX, _NY = range(7)


@njit(cache=True)
def signed_clearance(x, y, walls, side=UNKNOWN):
    """Distance from ``(x, y)`` to the nearest of packed ``walls`` ``(S, 6)``, negative unless in free space; a
    cell's certain axle answer ``side`` (:data:`AXLE_FREE`, :data:`AXLE_IN_WALL`) gives the sign without the
    crossing count."""
    d = _clearance(x, y, walls)
    if side == UNKNOWN:
        return d if free_at(x, y, walls) else -d
    return d if side == AXLE_FREE else -d


@njit(cache=True)
def point_class(clearance, tolerance):
    """The class of a bumper point of signed ``clearance``: :data:`IN_WALL`, :data:`NEAR` or :data:`CLEAR`."""
    if clearance < -tolerance:
        return IN_WALL
    return NEAR if clearance <= tolerance else CLEAR


@njit(cache=True)
def _disc_code(clearance, radius, tolerance):
    """The answers that hold on the whole disc of ``radius`` around a point of signed ``clearance``."""
    low, high = clearance - radius - _SLACK_CM, clearance + radius + _SLACK_CM
    code = UNKNOWN
    if high < -tolerance:
        code = IN_WALL
    elif low > tolerance:
        code = CLEAR
    elif low >= -tolerance and high <= tolerance:
        code = NEAR
    if low > 0.0:
        code |= AXLE_FREE
    elif high < 0.0:
        code |= AXLE_IN_WALL
    return code


@njit(cache=True)
def _certain(code):
    return (code & POINT_BITS) != UNKNOWN and (code & AXLE_BITS) != UNKNOWN


@njit(cache=True)
def _fill_codes(codes, walls, grid):
    """Every cell's code for ``walls``: a block of cells at once where the block's disc is certain."""
    x0, y0, cell, tolerance = grid[_X0], grid[_Y0], grid[_CELL], grid[_TOL]
    nx, ny = codes.shape
    cell_radius = cell * math.sqrt(0.5)
    for bx in range(0, nx, _BLOCK):
        for by in range(0, ny, _BLOCK):
            ex, ey = min(bx + _BLOCK, nx), min(by + _BLOCK, ny)
            cx, cy = x0 + 0.5 * (bx + ex) * cell, y0 + 0.5 * (by + ey) * cell
            code = _disc_code(signed_clearance(cx, cy, walls), 0.5 * cell * math.hypot(ex - bx, ey - by), tolerance)
            if _certain(code):
                codes[bx:ex, by:ey] = code
                continue
            for ix in range(bx, ex):
                for iy in range(by, ey):
                    px, py = x0 + (ix + 0.5) * cell, y0 + (iy + 0.5) * cell
                    codes[ix, iy] = _disc_code(signed_clearance(px, py, walls), cell_radius, tolerance)


@njit(cache=True)
def cell_code(x, y, codes, grid):
    """The code of the cell holding ``(x, y)``; :data:`UNKNOWN` off the grid."""
    fx, fy = (x - grid[_X0]) * grid[_INV_CELL], (y - grid[_Y0]) * grid[_INV_CELL]
    on_grid = (fx >= 0.0) & (fx < grid[_NX]) & (fy >= 0.0) & (fy < grid[_NY])
    # Selects, not branches: a pass of look-ups then runs without waiting on any of them.
    code = codes[int(fx) if on_grid else 0, int(fy) if on_grid else 0]
    return code if on_grid else UNKNOWN


class BumpSpaceTable:
    """The codes of one grid over ``bounds`` widened by ``margin_cm`` (where bumper points reach past the walls),
    one table per map slot (``codes (slots, nx, ny)`` uint8; ``grid``: the packed header the kernels read).

    Args:
        bounds: ``(x_min, y_min, x_max, y_max)`` holding every map the slots will get.
        tolerance_cm: the bump-space tolerance the point classes are judged against.
        margin_cm: how far past ``bounds`` points are tabulated (elsewhere the exact test answers).
        slots: how many maps.
        max_cells: the most cells of one slot's table; the cells grow from :data:`CELL_CM` to stay under it.
    """

    def __init__(self, bounds, tolerance_cm: float, margin_cm: float, slots: int = 1, max_cells: int = MAX_CELLS):
        x0, y0, x1, y1 = bounds
        x0, y0, x1, y1 = x0 - margin_cm, y0 - margin_cm, x1 + margin_cm, y1 + margin_cm
        cell = max(CELL_CM, math.sqrt((x1 - x0) * (y1 - y0) / max_cells))
        nx, ny = max(1, math.ceil((x1 - x0) / cell)), max(1, math.ceil((y1 - y0) / cell))
        self.grid = np.array([x0, y0, 1.0 / cell, cell, tolerance_cm, nx, ny], dtype=np.float64)
        self.codes = np.zeros((slots, nx, ny), dtype=np.uint8)

    @property
    def cell_cm(self) -> float:
        return float(self.grid[_CELL])

    def install(self, slot: int, walls: np.ndarray) -> None:
        """Tabulate ``walls`` (packed ``(S, 6)``) into slot ``slot``."""
        _fill_codes(self.codes[slot], walls, self.grid)
