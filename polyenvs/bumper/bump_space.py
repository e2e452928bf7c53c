"""The paper's bump-space filter (Dye, Part 3) as compiled kernels over particle arrays: what the estimator
:class:`polyenvs.estimators.bumper.BumpSpaceMCL` and the localization task (:mod:`polyenvs.bumper.localize`) both
run, one copy of the paper's algorithm on the family's floor.

Seed particles ``(x, y, heading)`` over the map; for each cycle move every particle by the logged odometry plus
normally distributed heading, forward and lateral error; discard the particles that are not in the *bump space*
(the band just inside the walls where the bumper touches a wall while the cart faces it, with a tolerance: the
paper's ``pointinside`` on the left, middle and right of the bumper); refill to the particle count by duplicating
the survivors evenly; repeat. The estimate is the densest cluster. No weights, no resampling noise: every random
number is motion noise. One update (three stages, the bump-space test, the refill and the estimate) is one compiled
call over the particle array (:func:`update_rows`: over a batch of them).

The bump-space test reads the map's answers from a table built once per map
(:class:`polyenvs.bumper.bump_tables.BumpSpaceTable`: whether the axle is free, whether a bumper point is in a wall,
near one or clear of them, per cell of a grid), and asks the exact geometry only in the cells a threshold crosses:
the same answers, so the same estimates, bit for bit. The update runs in passes over the particles (move, look up,
test, refill, estimate, back up); a particle's heading's cos and sin are computed once per stage, and a survivor's
reused by its duplicates' back-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from polyenvs.bumper.bump_tables import (
    AXLE_BITS,
    AXLE_IN_WALL,
    IN_WALL,
    MAX_CELLS,
    NEAR,
    POINT_BITS,
    UNKNOWN,
    BumpSpaceTable,
    cell_code,
    point_class,
    signed_clearance,
)
from polyenvs.bumper.maps import free_at
from polyenvs.bumper.odometry import odometry_step
from polyenvs.core.jit import njit
from polyenvs.core.parameters import check_parameters, documented, parameter, physical_parameters
from polyenvs.core.validation import check_in_range, check_int

__all__ = ["BumpSpaceFilter", "BumpSpaceSettings", "densest_cluster", "log_index", "mcl_update", "update_rows"]

#: A turn in radians, the headings' period.
_TURN = 2.0 * math.pi
#: Heading bins of the densest-cluster estimate.
_HEADING_BINS = 8


def log_index(context) -> tuple[np.ndarray, int]:
    """Where a cycle's log holds the ``(3, 2)`` stage ticks (turn, drive, back-up; left, right) and the bump bit."""
    s = context.observation_structure
    stages = [np.arange(*s[name]) for name in ("turn_ticks", "drive_ticks", "backup_ticks")]
    return np.stack(stages), s["bump"][0]


# Packed filter parameters.
_TICK, _BASE, _FRONT, _HALF, _TOL, _H0, _H1, _F0, _F1, _L0, _L1, _CELL, _GX, _GY, _NX, _NY = range(16)


@njit(cache=True)
def _stage_motion(a, b, params):
    """A stage's nominal chord ``(dx, dy, dheading)`` in the start frame, the cos and sin of half its turn, and the
    sd of its forward, lateral and heading errors (wheel travels ``a``, ``b``)."""
    theta = (b - a) / params[_BASE]
    nx, ny, nh = odometry_step(0.0, 0.0, 0.0, a, b, params[_BASE])
    dist = math.hypot(nx, ny)
    return (nx, ny, nh, math.cos(0.5 * nh), math.sin(0.5 * nh), params[_F0] + params[_F1] * dist,
            params[_L0] + params[_L1] * dist, params[_H0] + params[_H1] * abs(theta))  # fmt: skip


@njit(cache=True)
def _moved(pose, trig, motion, z):
    """``pose = (x, y, h)`` (``trig``: the cos and sin of ``h``) moved by a stage's ``motion`` with the standard
    normal errors ``z`` (forward along the chord, lateral across it, heading)."""
    x, y, h = pose
    c, s = trig
    nx, ny, nh, ch, sh, forward_sd, lateral_sd, heading_sd = motion
    forward, lateral, heading = z[0] * forward_sd, z[1] * lateral_sd, z[2] * heading_sd
    gx, gy = nx + forward * ch - lateral * sh, ny + forward * sh + lateral * ch
    return x + gx * c - gy * s, y + gx * s + gy * c, _turn_modulo(h + nh + heading + math.pi) - math.pi


@njit(cache=True)
def _turn_modulo(v):
    """``v % (2π)``, bit for bit, without numba's fmod call where ``v`` is within a turn of [0, 2π): there the
    remainder is ``v``, ``v - 2π`` (exact, Sterbenz) or ``v + 2π`` (as Python's modulo rounds it); zeros, far
    values and NaN take the modulo itself."""
    if 0.0 < v < _TURN:
        return v
    if _TURN <= v < 2.0 * _TURN:
        return v - _TURN
    if -_TURN < v < 0.0:
        return v + _TURN
    return v % _TURN


@njit(cache=True)
def _bumper_point(x, y, c, s, j, params):
    """The bumper's left (``j = 0``), middle and right point of a cart at ``(x, y)`` heading cos ``c``, sin ``s``."""
    ly = (j - 1) * params[_HALF]
    return x + params[_FRONT] * c - ly * s, y + params[_FRONT] * s + ly * c


@njit(cache=True)
def _look_up(spare, n, table, params, found):
    """The table's codes of each moved particle ``spare[i]`` ``(x, y, h, cos h, sin h)``: its axle and its three
    bumper points into ``found[i]``. A pass of its own, with no branch on what it finds, so that the loads overlap:
    made inside the test, each one stalled its particle's branches (the move-and-test step took 1.3-2x as long)."""
    codes, grid = table
    for i in range(n):
        x, y, c, s = spare[i, 0], spare[i, 1], spare[i, 3], spare[i, 4]
        found[i, 0] = cell_code(x, y, codes, grid)
        for j in range(3):
            px, py = _bumper_point(x, y, c, s, j, params)
            found[i, j + 1] = cell_code(px, py, codes, grid)


@njit(cache=True)
def _in_bump_space(pose, found, bump, walls, params):
    """The paper's test on the bumper's left, middle and right points (``pose = (x, y, cos h, sin h)``): with a
    bump, one of them within the tolerance of a wall and none deeper than it in the wall; without, none in a wall.
    The axle must be free. The answers are the table's ``found`` codes (a tuple: the axle's, then the points'),
    exactly where it has none."""
    x, y, c, s = pose
    axle = found[0] & AXLE_BITS
    if axle == AXLE_IN_WALL or (axle == UNKNOWN and not free_at(x, y, walls)):
        return False
    near = False
    for j in range(3):
        kind = found[j + 1] & POINT_BITS
        if kind == UNKNOWN:
            px, py = _bumper_point(x, y, c, s, j, params)
            kind = point_class(signed_clearance(px, py, walls, found[j + 1] & AXLE_BITS), params[_TOL])
        if kind == IN_WALL:
            return False
        near = near or kind == NEAR
    return near or not bump


@njit(cache=True)
def _bin_particles(particles, n, params, counts):
    """Each particle's (x, y, heading) cell ``(n, 3)``, and how many fall in each cell into ``counts``."""
    cell, gx, gy = params[_CELL], params[_GX], params[_GY]
    nx, ny = int(params[_NX]), int(params[_NY])
    counts[:] = 0
    bins = np.empty((n, 3), dtype=np.int64)
    for i in range(n):
        ix = min(max(int((particles[i, 0] - gx) / cell), 0), nx - 1)
        iy = min(max(int((particles[i, 1] - gy) / cell), 0), ny - 1)
        ih = int((particles[i, 2] + math.pi) / (2.0 * math.pi) * _HEADING_BINS) % _HEADING_BINS
        bins[i, 0], bins[i, 1], bins[i, 2] = ix, iy, ih
        counts[ix, iy, ih] += 1
    return bins


@njit(cache=True)
def _densest_cell(counts, nx, ny):
    """The cell whose 3 x 3 x 3 block (heading wrapping round) holds the most particles; the first of equals."""
    best, bx, by, bh = -1, 0, 0, 0
    for ix in range(nx):
        for iy in range(ny):
            for ih in range(_HEADING_BINS):
                if counts[ix, iy, ih] == 0:
                    continue
                total = 0
                for dx in range(-1, 2):
                    for dy in range(-1, 2):
                        if 0 <= ix + dx < nx and 0 <= iy + dy < ny:
                            for dh in range(-1, 2):
                                total += counts[ix + dx, iy + dy, (ih + dh) % _HEADING_BINS]
                if total > best:
                    best, bx, by, bh = total, ix, iy, ih
    return bx, by, bh


@njit(cache=True)
def densest_cluster(particles, n, params, counts, out):
    """Bin the particles in (x, y, heading) cells, take the cell with the most particles in it and its 26
    neighbours, and average the particles there (heading as a circular mean) into ``out``; returns how many
    particles that cluster holds."""
    bins = _bin_particles(particles, n, params, counts)
    bx, by, bh = _densest_cell(counts, int(params[_NX]), int(params[_NY]))
    sx = sy = sc = ss = 0.0
    m = 0
    for i in range(n):
        dh = (bins[i, 2] - bh) % _HEADING_BINS
        if abs(bins[i, 0] - bx) <= 1 and abs(bins[i, 1] - by) <= 1 and (dh <= 1 or dh == _HEADING_BINS - 1):
            sx += particles[i, 0]
            sy += particles[i, 1]
            sc += math.cos(particles[i, 2])
            ss += math.sin(particles[i, 2])
            m += 1
    out[0], out[1], out[2] = sx / m, sy / m, math.atan2(ss, sc)
    return m


@njit(cache=True)
def _keep_bump_space(particles, spare, ticks, bump, noise, model):  # noqa: PLR0917 - numba kernel: arguments passed positionally
    """Move every particle by the turn and the drive (in place) and copy those in the bump space, with the cos and
    sin of their heading, into ``spare`` ``(n, 5)``; returns how many. Three passes: move, look up, test."""
    params, walls, table = model
    n, tick = particles.shape[0], params[_TICK]
    turn = _stage_motion(ticks[0, 0] * tick, ticks[0, 1] * tick, params)
    drive = _stage_motion(ticks[1, 0] * tick, ticks[1, 1] * tick, params)
    for i in range(n):
        x, y, h = particles[i, 0], particles[i, 1], particles[i, 2]
        x, y, h = _moved((x, y, h), (math.cos(h), math.sin(h)), turn, noise[i, 0])
        x, y, h = _moved((x, y, h), (math.cos(h), math.sin(h)), drive, noise[i, 1])
        particles[i, 0], particles[i, 1], particles[i, 2] = x, y, h
        spare[i, 0], spare[i, 1], spare[i, 2], spare[i, 3], spare[i, 4] = x, y, h, math.cos(h), math.sin(h)
    found = np.empty((n, 4), dtype=np.uint8)
    _look_up(spare, n, table, params, found)
    kept = 0
    for i in range(n):  # survivors move down within spare: kept <= i, so row i is read before it is overwritten
        x, y, h, c, s = spare[i, 0], spare[i, 1], spare[i, 2], spare[i, 3], spare[i, 4]
        codes = (found[i, 0], found[i, 1], found[i, 2], found[i, 3])
        if _in_bump_space((x, y, c, s), codes, bump, walls, params):
            spare[kept, 0], spare[kept, 1], spare[kept, 2], spare[kept, 3], spare[kept, 4] = x, y, h, c, s
            kept += 1
    return kept


@njit(cache=True)
def mcl_update(cloud, log, noise, model, out):
    """One cycle: move by the turn and the drive, keep the bump-space particles, refill, estimate (into ``out``),
    move by the back-up. ``out`` gets (x, y, heading) and, if it has room, the estimate cluster's particle count.
    ``cloud = (particles, spare, counts)``: the particles, room ``(n, 5)`` for the survivors and the estimate's
    bins; ``log = (ticks, bump)``: the cycle's ``(3, 2)`` stage ticks and bump bit; ``model = (params, walls,
    table)``, the table the map's :class:`~polyenvs.bumper.bump_tables.BumpSpaceTable` codes and grid. Returns the
    number of survivors (0: the set emptied and was left moved, unestimated)."""
    particles, spare, counts = cloud
    ticks, bump = log
    params = model[0]
    n = particles.shape[0]
    kept = _keep_bump_space(particles, spare, ticks, bump, noise, model)
    if kept == 0:
        return 0
    j = 0  # i % kept, counted rather than divided
    for i in range(n):  # duplicate the survivors evenly
        particles[i, 0], particles[i, 1], particles[i, 2] = spare[j, 0], spare[j, 1], spare[j, 2]
        j = j + 1 if j + 1 < kept else 0
    in_cluster = densest_cluster(particles, n, params, counts, out)
    if out.shape[0] > 3:  # room for the cluster's particle count (the localization task observes it)
        out[3] = in_cluster
    backup = _stage_motion(ticks[2, 0] * params[_TICK], ticks[2, 1] * params[_TICK], params)
    j = 0
    for i in range(n):  # a duplicate's heading is its survivor's: its cos and sin too
        x, y, h = _moved((spare[j, 0], spare[j, 1], spare[j, 2]), (spare[j, 3], spare[j, 4]), backup, noise[i, 2])
        particles[i, 0], particles[i, 1], particles[i, 2] = x, y, h
        j = j + 1 if j + 1 < kept else 0
    return kept


@njit(cache=True)
def update_rows(actions, clouds, logs, model, estimates):
    """:func:`mcl_update` for every row ``b`` with ``actions[b, 1] >= 0.5`` (a batch of localizers, one per cart,
    sharing the model but the walls, ``(slots, S, 6)``, and the table's codes, ``(slots, nx, ny)``: one map for
    all, or one per row): ``clouds = (particles, noise, spare, counts)`` with ``particles (B, n, 3)``, ``noise (B,
    n, 3, 3)`` (each row's draws for this cycle) and one scratch ``spare`` ``(n, 5)`` and ``counts``; ``model =
    (params, walls, (codes, grid), ticks_at, bump_at)``; ``logs (B, >= 7)`` the cycles' logs (ticks then bump, as
    ``log_index`` says: ``logs[b, ticks]`` reshaped ``(3, 2)``); ``estimates (B, 5)`` receives each updated row's
    estimate (x, y, heading), its cluster's particle count and its survivors."""
    particles, noise, spare, counts = clouds
    params, walls, (codes, grid), ticks_at, bump_at = model
    shared = walls.shape[0] == 1
    ticks = np.empty((3, 2))
    for b in range(actions.shape[0]):
        if actions[b, 1] < 0.5:
            continue
        for k in range(6):
            ticks[k // 2, k % 2] = logs[b, ticks_at[k]]
        slot = 0 if shared else b
        kept = mcl_update((particles[b], spare, counts), (ticks, logs[b, bump_at] > 0.5), noise[b],
                          (params, walls[slot], (codes[slot], grid)), estimates[b])  # fmt: skip
        estimates[b, 4] = kept


@documented
@dataclass(frozen=True)
class BumpSpaceSettings:
    """The filter's motion errors per stage (``sd = *_sd + *_frac x`` the stage's turn or distance), its bump-space
    tolerance (the paper's ``pointinside`` tolerance: 0.5 cm empties the set far more often, a loose one blurs the
    map into symmetry) and the densest-cluster estimate's cell (heading cells are 45°).

    {parameters}
    """

    heading_sd_deg: float = parameter(2.0, 0.0, 90.0, "deg", "feasibility study")
    heading_sd_frac: float = parameter(0.05, 0.0, 1.0, "of the turn", "feasibility study")
    forward_sd_cm: float = parameter(0.6, 0.0, 50.0, "cm", "feasibility study")
    forward_sd_frac: float = parameter(0.06, 0.0, 1.0, "of the distance", "feasibility study")
    lateral_sd_cm: float = parameter(0.6, 0.0, 50.0, "cm", "feasibility study")
    lateral_sd_frac: float = parameter(0.06, 0.0, 1.0, "of the distance", "feasibility study")
    tolerance_cm: float = parameter(1.5, 0.0, 50.0, "cm", "ours, for the paper's pointinside test")
    cluster_cm: float = parameter(10.0, 1.0, 100.0, "cm", "ours")

    def __post_init__(self):
        check_parameters(self)


class BumpSpaceFilter:
    """The filter's settings and packed model, and the particles' seeding (the estimator and the task build on it).

    Args:
        particles: particle count, in [10, 100000]; the paper found 700 or more necessary. Measured in the
            paper's arena (100 runs of 15 bumps), runs whose particle set emptied: 0.83 / 0.52 / 0.29 / 0.15 /
            0.12 at 100 / 300 / 500 / 700 / 1,000, the knee at 700 as the paper says; the median position error
            at bump 10 is still 35 cm at 700 against 13 cm at 1,000.
        bumper_width_cm, bumper_offset_cm: the bumper the test uses (default: the context's nominal cart).
        **settings: the motion errors, the bump-space tolerance and the estimate's cell, by name
            (:class:`BumpSpaceSettings`: default 2° + 5% of the turn for the heading, 0.6 cm + 6% of the distance
            forward and laterally, 1.5 cm, 10 cm).

    Every argument after ``particles`` is keyword-only.
    """

    def __init__(
        self,
        particles: int = 1000,
        *,
        bumper_width_cm: float | None = None,
        bumper_offset_cm: float | None = None,
        **settings,
    ):
        # Python's own TypeError for an unknown keyword, as when these were the constructor's own parameters.
        checked = physical_parameters(BumpSpaceFilter, BumpSpaceSettings, settings)
        self.n = check_int("particles", particles, 10, 100_000)
        self.heading = (checked.heading_sd_deg, checked.heading_sd_frac)
        self.forward = (checked.forward_sd_cm, checked.forward_sd_frac)
        self.lateral = (checked.lateral_sd_cm, checked.lateral_sd_frac)
        self.tolerance_cm = checked.tolerance_cm
        self.bumper_width_cm = (
            None if bumper_width_cm is None else check_in_range("bumper_width_cm", bumper_width_cm, 1.0, 50.0)
        )
        self.bumper_offset_cm = (
            None if bumper_offset_cm is None else check_in_range("bumper_offset_cm", bumper_offset_cm, 0.0, 50.0)
        )
        self.cluster_cm = checked.cluster_cm

    def configure(self, context, bounds=None) -> None:
        """Pack the filter's parameters for ``context`` (the map and the cart's nominal geometry): ``params``,
        ``walls``, the estimate's bins ``counts`` over ``bounds`` (default: the map's; a box holding several
        maps lets one packing serve them all) and where a log holds the ticks and the bump bit."""
        self.context = context
        world = context.world
        x0, y0, x1, y1 = world.bounds if bounds is None else bounds
        nx, ny = max(1, math.ceil((x1 - x0) / self.cluster_cm)), max(1, math.ceil((y1 - y0) / self.cluster_cm))
        width = context.bumper_width_cm if self.bumper_width_cm is None else self.bumper_width_cm
        offset = context.bumper_offset_cm if self.bumper_offset_cm is None else self.bumper_offset_cm
        self._tick_index, self._bump_index = log_index(context)
        self.params = np.array([
            context.tick_cm, context.wheel_base_cm, offset, width / 2, self.tolerance_cm,
            math.radians(self.heading[0]), self.heading[1], *self.forward, *self.lateral, self.cluster_cm, x0, y0,
            nx, ny,
        ])  # fmt: skip
        self.walls = None if world is None else world.walls
        self.counts = np.zeros((nx, ny, _HEADING_BINS), dtype=np.int64)

    def make_table(self, bounds, slots: int = 1, max_cells: int = MAX_CELLS) -> BumpSpaceTable:
        """An empty :class:`~polyenvs.bumper.bump_tables.BumpSpaceTable` of ``slots`` maps in ``bounds`` for this
        filter's tolerance, reaching as far past the walls as its bumper does (after :meth:`configure`)."""
        reach = math.hypot(self.params[_FRONT], self.params[_HALF]) + self.tolerance_cm
        return BumpSpaceTable(bounds, self.tolerance_cm, reach, slots, max_cells)

    def seed_particles(self, rng: np.random.Generator, world=None) -> np.ndarray:
        """``(n, 3)`` particles uniform over the free space of ``world`` (default: the context's; the axle at least
        half the bumper's width from every wall), drawn on ``rng`` (after :meth:`configure`)."""
        world = self.context.world if world is None else world
        x0, y0, x1, y1 = world.bounds
        margin = self.params[_HALF]
        out = np.empty((0, 3))
        while len(out) < self.n:
            batch = rng.random((2 * self.n, 3)) * [x1 - x0, y1 - y0, 2 * np.pi] + [x0, y0, -np.pi]
            out = np.concatenate([out, batch[world.clearance(batch[:, :2]) >= margin]])
        return np.ascontiguousarray(out[: self.n])
