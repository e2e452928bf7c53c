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
def build_grid(pose, active, geometry, shape, start, items, cell_of):
    """Counting sort of the active robots into cells (environment-major): cell ``c`` holds
    ``items[start[c]:start[c + 1]]``."""
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
def _segment_distance_sq(px, py, x0, y0, x1, y1):
    dx, dy = x1 - x0, y1 - y0
    length_sq = dx * dx + dy * dy
    t = 0.0
    if length_sq > 0.0:
        t = min(max(((px - x0) * dx + (py - y0) * dy) / length_sq, 0.0), 1.0)
    ex, ey = x0 + t * dx - px, y0 + t * dy - py
    return ex * ex + ey * ey


@njit(cache=True, inline="always")
def _ray_circle(ox, oy, dx, dy, cx, cy, r, best):
    """Distance along the unit ray to the circle, if below ``best`` (0 when the origin is inside)."""
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
def _ray_segment(ox, oy, dx, dy, x0, y0, x1, y1, best):
    """The smaller of ``best`` and the distance along the ray (o, d) to segment (x0, y0)-(x1, y1). Scalars, inlined
    into the compiled beam loop: a compiled-kernel boundary (packing them would cost a tuple per wall)."""
    ex, ey = x1 - x0, y1 - y0
    denom = dx * ey - dy * ex
    if denom == 0.0:
        return best
    wx, wy = x0 - ox, y0 - oy
    t = (wx * ey - wy * ex) / denom
    u = (wx * dy - wy * dx) / denom
    if 0.0 <= t < best and 0.0 <= u <= 1.0:
        return t
    return best


@njit(cache=True)
def move(pose, active, wheels, params, walls, circles, geometry, shape, start, items, cell_of, proposal, blocked):
    """Advance every active robot by one control period; ``blocked[i]`` = 1 where a contact refused the move. A
    compiled-kernel boundary: its arrays are positional, as numba takes them.

    Args:
        wheels: ``(N, 2)`` left and right wheel speeds (m/s).
        params: ``[dt_s, wheel_base_m, radius_m]``.
        proposal: ``(N, 3)`` scratch.
    """
    dt, base, radius = params[0], params[1], params[2]
    nx, ny, per = shape[0], shape[1], shape[2]
    n = pose.shape[0]
    r2 = radius * radius
    contact = 4.0 * r2
    for i in range(n):
        blocked[i] = 0
        if not active[i]:
            continue
        v = 0.5 * (wheels[i, 0] + wheels[i, 1]) * dt
        dtheta = (wheels[i, 1] - wheels[i, 0]) * dt / base
        # The chord of the arc: length v * sinc(dtheta / 2) along the mean heading.
        half = 0.5 * dtheta
        chord = v if abs(half) < 1e-9 else v * math.sin(half) / half
        h = pose[i, 2] + half
        proposal[i, 0] = pose[i, 0] + chord * math.cos(h)
        proposal[i, 1] = pose[i, 1] + chord * math.sin(h)
        heading = pose[i, 2] + dtheta
        proposal[i, 2] = math.atan2(math.sin(heading), math.cos(heading))
    for i in range(n):
        if not active[i]:
            continue
        px, py = proposal[i, 0], proposal[i, 1]
        if px == pose[i, 0] and py == pose[i, 1]:
            continue  # turning in place never overlaps anything
        e = i // per
        ws = walls[e if walls.shape[0] > 1 else 0]
        cs = circles[e if circles.shape[0] > 1 else 0]
        hit = False
        for w in range(ws.shape[0]):
            if _segment_distance_sq(px, py, ws[w, 0], ws[w, 1], ws[w, 2], ws[w, 3]) < r2:
                hit = True
                break
        if not hit:
            for c in range(cs.shape[0]):
                ex, ey = px - cs[c, 0], py - cs[c, 1]
                reach = cs[c, 2] + radius
                if ex * ex + ey * ey < reach * reach:
                    hit = True
                    break
        if not hit:
            first = e * nx * ny
            cx, cy = (cell_of[i] - first) % nx, (cell_of[i] - first) // nx
            for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
                for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                    c = first + gy * nx + gx
                    for s in range(start[c], start[c + 1]):
                        j = items[s]
                        if j == i:
                            continue
                        ex, ey = px - pose[j, 0], py - pose[j, 1]
                        fx, fy = px - proposal[j, 0], py - proposal[j, 1]
                        if ex * ex + ey * ey < contact or fx * fx + fy * fy < contact:
                            hit = True
        blocked[i] = 1 if hit else 0
    for i in range(n):
        if active[i]:
            if not blocked[i]:
                pose[i, 0] = proposal[i, 0]
                pose[i, 1] = proposal[i, 1]
            pose[i, 2] = proposal[i, 2]


@njit(cache=True)
def sense(pose, active, todo, params, angles, walls, circles, geometry, shape, start, items, cell_of, beams,
          nb_index, nb_range, clearance):  # fmt: skip
    """Cast every active robot's beams, find its k nearest robots in range, and measure its clearance. A
    compiled-kernel boundary: its arrays are positional, as numba takes them (one call senses the whole batch).

    Args:
        todo: ``(N,)`` uint8: the rows to sense (a vector env re-senses only the environments it has just reset);
            the outputs of the other rows are left as they are.
        params: ``[radius_m, beam_m, comm_range_m]``.
        angles: ``(S,)`` sensor angles (rad) relative to the heading; beams start on the rim.
        beams: ``(N, S)`` out: distance along each beam to the first wall, obstacle or robot, ``inf`` if none
            within ``beam_m``.
        nb_index, nb_range: ``(N, k)`` out: the k nearest other active robots within ``comm_range_m`` by centre
            distance, nearest first (index -1 and range ``inf`` in unused slots).
        clearance: ``(N,)`` out: gap (m) between the robot's rim and the nearest wall, obstacle or robot (robots
            count only within a beam's reach, ``beam_m``).
    """
    radius, beam_m, comm = params[0], params[1], params[2]
    nx, ny, per = shape[0], shape[1], shape[2]
    n, n_sensors = beams.shape
    k = nb_index.shape[1]
    comm_sq = comm * comm
    # A robot farther than this (centre to centre) is beyond every beam of robot i.
    seen_sq = (2.0 * radius + beam_m) ** 2
    ray = np.empty((n_sensors, 4))
    for i in range(n):
        if not todo[i]:
            continue
        for s in range(n_sensors):
            beams[i, s] = np.inf
        for q in range(k):
            nb_index[i, q] = -1
            nb_range[i, q] = np.inf
        clearance[i] = np.inf
        if not active[i]:
            continue
        x, y, h = pose[i, 0], pose[i, 1], pose[i, 2]
        e = i // per
        ws = walls[e if walls.shape[0] > 1 else 0]
        cs = circles[e if circles.shape[0] > 1 else 0]
        gap = np.inf
        for w in range(ws.shape[0]):
            d = math.sqrt(_segment_distance_sq(x, y, ws[w, 0], ws[w, 1], ws[w, 2], ws[w, 3]))
            gap = min(gap, d - radius)
        for c in range(cs.shape[0]):
            d = math.hypot(x - cs[c, 0], y - cs[c, 1]) - cs[c, 2] - radius
            gap = min(gap, d)
        for s in range(n_sensors):
            dx, dy = math.cos(h + angles[s]), math.sin(h + angles[s])
            ox, oy = x + radius * dx, y + radius * dy
            ray[s, 0], ray[s, 1], ray[s, 2], ray[s, 3] = ox, oy, dx, dy
            best = beam_m
            for w in range(ws.shape[0]):
                best = _ray_segment(ox, oy, dx, dy, ws[w, 0], ws[w, 1], ws[w, 2], ws[w, 3], best)
            for c in range(cs.shape[0]):
                best = _ray_circle(ox, oy, dx, dy, cs[c, 0], cs[c, 1], cs[c, 2], best)
            beams[i, s] = best
        first = e * nx * ny
        cx, cy = (cell_of[i] - first) % nx, (cell_of[i] - first) // nx
        for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
            for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                c = first + gy * nx + gx
                for t in range(start[c], start[c + 1]):
                    j = items[t]
                    if j == i:
                        continue
                    ex, ey = pose[j, 0] - x, pose[j, 1] - y
                    d_sq = ex * ex + ey * ey
                    if d_sq <= seen_sq:
                        gap = min(gap, math.sqrt(d_sq) - 2.0 * radius)
                        for s in range(n_sensors):
                            beams[i, s] = _ray_circle(ray[s, 0], ray[s, 1], ray[s, 2], ray[s, 3], pose[j, 0], pose[j, 1],
                                                      radius, beams[i, s])  # fmt: skip
                    if d_sq <= comm_sq:
                        d = math.sqrt(d_sq)
                        q = k - 1
                        if d < nb_range[i, q] or (d == nb_range[i, q] and j < nb_index[i, q]):
                            # Insertion into the sorted slots (ties by index: the same order every run).
                            while q > 0 and (
                                d < nb_range[i, q - 1] or (d == nb_range[i, q - 1] and j < nb_index[i, q - 1])
                            ):
                                nb_range[i, q] = nb_range[i, q - 1]
                                nb_index[i, q] = nb_index[i, q - 1]
                                q -= 1
                            nb_range[i, q] = d
                            nb_index[i, q] = j
        for s in range(n_sensors):
            if beams[i, s] >= beam_m:
                beams[i, s] = np.inf
        clearance[i] = max(gap, 0.0)
