"""The batched core: N differential-drive robots among wall segments and circular obstacles, in compiled loops.

Physics apart from task apart from API: nothing here knows about Gymnasium, PettingZoo, rewards or the goal.

Layout (batch axis first, one row per robot):

- ``pose`` ``(E * N, 3)``: x, y (m), heading (rad, counter-clockwise from +x), for E environments of N robots
  (rows ``e * N .. e * N + N - 1`` are environment e's; a single environment is a batch of one);
- ``active`` ``(E * N,)`` uint8: robots still in the episode (the others are neither moved, sensed nor hit);
- ``walls`` ``(E or 1, W, 4)``: segments x0, y0, x1, y1 (m); ``circles`` ``(E or 1, C, 3)``: x, y, radius (m)
  (a leading 1 shares them between environments; unused circle slots sit far away with radius 0);
- a uniform grid of cells per environment (a cell list rebuilt every step by a counting sort), so that beams,
  contacts and trilateration look at the robots of the 3 x 3 cells around a robot instead of all N: the cell
  side is at least the farthest any of those reaches (see :func:`cell_size`), so N = 256 costs about what N = 20
  costs per robot, and robots of different environments never meet.

Contacts: every robot proposes its move (an exact arc of the differential drive), and a proposal whose disc would
overlap a wall, an obstacle, another robot's current disc or another robot's proposed disc is refused (the robot
still turns in place). Whichever subset of proposals is refused, the result has no overlap, so no order enters.
A move shorter than the body radius cannot jump a zero-thickness wall either: the crossing point would lie
within the move of the proposal, closer than the radius. The environments bound the step accordingly.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.geometry2d import point_segment_distance_sq, ray_circle_hit, ray_segment_hit
from polyenvs.core.jit import njit

__all__ = ["Grid", "build_grid", "cell_size", "move", "sense"]


def cell_size(radius: float, beam_m: float, comm_range_m: float, max_step_m: float) -> float:
    """The smallest cell side for which the 3 x 3 cells around a robot hold every robot it can touch, see with a
    beam or hear by trilateration."""
    return max(comm_range_m, 2.0 * radius + beam_m, 2.0 * radius + 2.0 * max_step_m)


class Grid:
    """The cell list over the arena's bounding box (robots never leave it: walls enclose every arena)."""

    def __init__(self, bounds, cell: float, n_robots: int, n_envs: int = 1):
        xmin, ymin, xmax, ymax = bounds
        nx = max(1, math.ceil((xmax - xmin) / cell))
        ny = max(1, math.ceil((ymax - ymin) / cell))
        #: ``[nx, ny, robots per environment]``.
        self.shape = np.array([nx, ny, n_robots], dtype=np.int64)
        self.geometry = np.array([xmin, ymin, 1.0 / cell, 0.0])
        self.start = np.zeros(n_envs * nx * ny + 1, dtype=np.int64)
        self.items = np.zeros(n_envs * n_robots, dtype=np.int64)
        self.cell_of = np.zeros(n_envs * n_robots, dtype=np.int64)

    @property
    def arrays(self) -> tuple:
        """What the kernels take: ``(geometry, shape, start, items, cell_of)``."""
        return self.geometry, self.shape, self.start, self.items, self.cell_of


@njit(cache=True)
def build_grid(pose, active, grid):
    """Counting sort of the active robots into cells (environment-major): cell ``c`` holds
    ``items[start[c]:start[c + 1]]``. ``grid``: :attr:`Grid.arrays`."""
    geometry, shape, start, items, cell_of = grid
    nx, ny, per = shape[0], shape[1], shape[2]
    start[:] = 0
    n = pose.shape[0]
    for i in range(n):
        if active[i]:
            cx = min(max(int((pose[i, 0] - geometry[0]) * geometry[2]), 0), nx - 1)
            cy = min(max(int((pose[i, 1] - geometry[1]) * geometry[2]), 0), ny - 1)
            c = (i // per) * nx * ny + cy * nx + cx
            cell_of[i] = c
            start[c + 1] += 1
        else:
            cell_of[i] = -1
    for c in range(start.shape[0] - 1):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    for i in range(n):
        c = cell_of[i]
        if c >= 0:
            items[fill[c]] = i
            fill[c] += 1


@njit(cache=True, inline="always")
def _scene_of(scene, e):
    """Environment ``e``'s walls and circles from ``scene = (walls, circles)`` (a leading 1 is shared)."""
    walls, circles = scene
    return walls[e if walls.shape[0] > 1 else 0], circles[e if circles.shape[0] > 1 else 0]


@njit(cache=True, inline="always")
def _cells_around(i, shape, cell_of):
    """Robot ``i``'s environment's first cell and the 3 x 3 window of cells around its own: ``(first, x0, x1, y0,
    y1)``, ranges clipped to the grid."""
    nx, ny, per = shape[0], shape[1], shape[2]
    first = (i // per) * nx * ny
    cx, cy = (cell_of[i] - first) % nx, (cell_of[i] - first) // nx
    return first, max(cx - 1, 0), min(cx + 2, nx), max(cy - 1, 0), min(cy + 2, ny)


@njit(cache=True, inline="always")
def _wall_segment(walls, w):
    return walls[w, 0], walls[w, 1], walls[w, 2], walls[w, 3]


@njit(cache=True)
def _propose(pose, wheels, params, proposal):
    """One robot's next pose, an exact arc of the differential drive: row ``pose`` driven by its ``wheels`` for a
    control period (``params = [dt_s, wheel_base_m, radius_m]``), written into row ``proposal``."""
    dt, base = params[0], params[1]
    v = 0.5 * (wheels[0] + wheels[1]) * dt
    dtheta = (wheels[1] - wheels[0]) * dt / base
    # The chord of the arc: length v * sinc(dtheta / 2) along the mean heading.
    half = 0.5 * dtheta
    chord = v if abs(half) < 1e-9 else v * math.sin(half) / half
    h = pose[2] + half
    proposal[0] = pose[0] + chord * math.cos(h)
    proposal[1] = pose[1] + chord * math.sin(h)
    heading = pose[2] + dtheta
    proposal[2] = math.atan2(math.sin(heading), math.cos(heading))


@njit(cache=True)
def _collides(i, pose, proposal, radius, scene, grid):
    """Whether robot ``i``'s proposed disc overlaps a wall, an obstacle, or another robot's current or proposed
    disc (the robots of the 3 x 3 cells around it)."""
    px, py = proposal[i, 0], proposal[i, 1]
    r2 = radius * radius
    walls, circles = _scene_of(scene, i // grid[1][2])
    for w in range(walls.shape[0]):
        if point_segment_distance_sq(px, py, _wall_segment(walls, w)) < r2:
            return True
    for c in range(circles.shape[0]):
        ex, ey = px - circles[c, 0], py - circles[c, 1]
        reach = circles[c, 2] + radius
        if ex * ex + ey * ey < reach * reach:
            return True
    _, shape, start, items, cell_of = grid
    first, x0, x1, y0, y1 = _cells_around(i, shape, cell_of)
    contact = 4.0 * r2
    for gy in range(y0, y1):
        for gx in range(x0, x1):
            c = first + gy * shape[0] + gx
            for s in range(start[c], start[c + 1]):
                j = items[s]
                if j != i:
                    ex, ey = px - pose[j, 0], py - pose[j, 1]
                    fx, fy = px - proposal[j, 0], py - proposal[j, 1]
                    if ex * ex + ey * ey < contact or fx * fx + fy * fy < contact:
                        return True
    return False


@njit(cache=True)
def move(pose, active, wheels, params, scene, grid, scratch):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Advance every active robot by one control period; a contact refuses the move (the robot still turns).

    Args:
        wheels: ``(N, 2)`` left and right wheel speeds (m/s).
        params: ``[dt_s, wheel_base_m, radius_m]``.
        scene: ``(walls, circles)``; grid: :attr:`Grid.arrays` (built for ``pose``).
        scratch: ``(proposal, blocked)``: ``(N, 3)`` scratch, and ``(N,)`` out, 1 where a contact refused the move.
    """
    proposal, blocked = scratch
    n = pose.shape[0]
    for i in range(n):
        blocked[i] = 0
        if active[i]:
            _propose(pose[i], wheels[i], params, proposal[i])
    for i in range(n):
        # Turning in place never overlaps anything.
        if active[i] and (proposal[i, 0] != pose[i, 0] or proposal[i, 1] != pose[i, 1]):
            blocked[i] = 1 if _collides(i, pose, proposal, params[2], scene, grid) else 0
    for i in range(n):
        if active[i]:
            if not blocked[i]:
                pose[i, 0] = proposal[i, 0]
                pose[i, 1] = proposal[i, 1]
            pose[i, 2] = proposal[i, 2]


@njit(cache=True)
def _static_gap(x, y, radius, walls, circles):
    """Gap (m) between the rim of a robot at (x, y) and the nearest wall or obstacle."""
    gap = np.inf
    for w in range(walls.shape[0]):
        gap = min(gap, math.sqrt(point_segment_distance_sq(x, y, _wall_segment(walls, w))) - radius)
    for c in range(circles.shape[0]):
        gap = min(gap, math.hypot(x - circles[c, 0], y - circles[c, 1]) - circles[c, 2] - radius)
    return gap


@njit(cache=True)
def _cast_beams(pose, params, angles, scene_row, ray, beams):
    """One robot's beams (row ``pose``) against its environment's ``scene_row = (walls, circles)``: ``beams`` the
    distance along each to the first hit, ``beam_m`` if none; ``ray`` ``(S, 4)`` out: each beam's origin on the rim
    and its direction."""
    walls, circles = scene_row
    x, y, h = pose[0], pose[1], pose[2]
    radius, beam_m = params[0], params[1]
    for s in range(angles.shape[0]):
        dx, dy = math.cos(h + angles[s]), math.sin(h + angles[s])
        ox, oy = x + radius * dx, y + radius * dy
        ray[s, 0], ray[s, 1], ray[s, 2], ray[s, 3] = ox, oy, dx, dy
        best = beam_m
        for w in range(walls.shape[0]):
            x0, y0, x1, y1 = _wall_segment(walls, w)
            best = ray_segment_hit((ox, oy, dx, dy), (x0, y0, x1 - x0, y1 - y0), best)
        for c in range(circles.shape[0]):
            best = ray_circle_hit((ox, oy, dx, dy), (circles[c, 0], circles[c, 1], circles[c, 2]), best)
        beams[s] = best


@njit(cache=True, inline="always")
def _insert_neighbour(index, distance, j, d):
    """Robot ``j`` at centre distance ``d`` into the sorted slots ``index``/``distance`` if it is among the k
    nearest (ties by index: the same order every run)."""
    q = index.shape[0] - 1
    if d < distance[q] or (d == distance[q] and j < index[q]):
        while q > 0 and (d < distance[q - 1] or (d == distance[q - 1] and j < index[q - 1])):
            distance[q] = distance[q - 1]
            index[q] = index[q - 1]
            q -= 1
        distance[q] = d
        index[q] = j


@njit(cache=True)
def _meet_robots(i, pose, params, grid, ray, out, gap):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Robot ``i`` against the robots of the 3 x 3 cells around it: they block its beams (``ray`` from
    :func:`_cast_beams`) and narrow its gap within a beam's reach, and fill its k nearest-neighbour slots within
    ``comm_range_m``. Returns the gap."""
    beams, nb_index, nb_range, _ = out
    radius, beam_m, comm = params[0], params[1], params[2]
    comm_sq = comm * comm
    # A robot farther than this (centre to centre) is beyond every beam of robot i.
    seen_sq = (2.0 * radius + beam_m) ** 2
    _, shape, start, items, cell_of = grid
    first, x0, x1, y0, y1 = _cells_around(i, shape, cell_of)
    x, y = pose[i, 0], pose[i, 1]
    for gy in range(y0, y1):
        for gx in range(x0, x1):
            c = first + gy * shape[0] + gx
            for t in range(start[c], start[c + 1]):
                j = items[t]
                if j == i:
                    continue
                ex, ey = pose[j, 0] - x, pose[j, 1] - y
                d_sq = ex * ex + ey * ey
                if d_sq <= seen_sq:
                    gap = min(gap, math.sqrt(d_sq) - 2.0 * radius)
                    for s in range(beams.shape[1]):
                        beam = (ray[s, 0], ray[s, 1], ray[s, 2], ray[s, 3])
                        beams[i, s] = ray_circle_hit(beam, (pose[j, 0], pose[j, 1], radius), beams[i, s])
                if d_sq <= comm_sq:
                    _insert_neighbour(nb_index[i], nb_range[i], j, math.sqrt(d_sq))
    return gap


@njit(cache=True)
def sense(pose, active, todo, params, angles, scene, grid, out):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Cast every active robot's beams, find its k nearest robots in range, and measure its clearance (one call
    senses the whole batch).

    Args:
        todo: ``(N,)`` uint8: the rows to sense (a vector env re-senses only the environments it has just reset);
            the outputs of the other rows are left as they are.
        params: ``[radius_m, beam_m, comm_range_m]``.
        angles: ``(S,)`` sensor angles (rad) relative to the heading; beams start on the rim.
        scene: ``(walls, circles)``; grid: :attr:`Grid.arrays` (built for ``pose``).
        out: ``(beams, nb_index, nb_range, clearance)``, written: ``beams`` ``(N, S)`` distance along each beam to
            the first wall, obstacle or robot, ``inf`` if none within ``beam_m``; ``nb_index``, ``nb_range``
            ``(N, k)`` the k nearest other active robots within ``comm_range_m`` by centre distance, nearest first
            (index -1 and range ``inf`` in unused slots); ``clearance`` ``(N,)`` gap (m) between the robot's rim
            and the nearest wall, obstacle or robot (robots count only within a beam's reach, ``beam_m``).
    """
    beams, nb_index, nb_range, clearance = out
    radius, beam_m = params[0], params[1]
    ray = np.empty((beams.shape[1], 4))
    for i in range(pose.shape[0]):
        if not todo[i]:
            continue
        beams[i, :] = np.inf
        nb_index[i, :] = -1
        nb_range[i, :] = np.inf
        clearance[i] = np.inf
        if not active[i]:
            continue
        scene_row = _scene_of(scene, i // grid[1][2])
        gap = _static_gap(pose[i, 0], pose[i, 1], radius, scene_row[0], scene_row[1])
        _cast_beams(pose[i], params, angles, scene_row, ray, beams[i])
        gap = _meet_robots(i, pose, params, grid, ray, out, gap)
        for s in range(beams.shape[1]):
            if beams[i, s] >= beam_m:
                beams[i, s] = np.inf
        clearance[i] = max(gap, 0.0)
