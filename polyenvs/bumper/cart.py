"""The bumper cart's batched, closed-form cycle simulator (the physics core; never imports Gymnasium).

One cycle is the paper's control loop in three stages: turn in place by a commanded angle, drive until the bumper
trips (or a maximum distance), back up. In each stage both motors run at constant, unmatched speeds, so the cart
moves on one circular arc (a straight line, or a spin, at the limits). The body is a rectangle whose front edge is
the bumper (it covers the whole profile, as in the paper). Every point of the body moves on a circle about the
arc's centre, so the first contact with the walls is the smallest root of a few closed-form equations, not the
end of a time-stepped search:

- a body corner crossing a wall segment into the wall, and
- a wall vertex crossing a body edge into the body (in the cart's frame the vertex moves on the reverse arc).

A crossing's direction is judged against the fixed inner side of what is crossed, never against the side the
moving point starts on: a point on a circle crosses a line twice, and the first time may be beyond the segment's
end (round a wall corner that juts into the room, or a body corner), so the second, through the segment itself,
is the one that enters. The inside of the body is the axle's side of each edge; a wall row carries the side free
space lies on (column 5 of :attr:`polyenvs.bumper.maps.BumperMap.walls`, +1 left of the segment, -1 right).

A point ``p`` moving through angle ``φ = tθ`` (``θ`` the stage's heading change, ``t`` in [0, 1]) is
``p + (sin φ / θ) J w - ((1 - cos φ) / θ) w`` with ``w = θ (p - axle) - s n`` (``s`` the axle's arc length, ``n``
the cart's left normal, ``J`` a quarter turn): regular as ``θ -> 0``. Its signed distance to a wall line is
``c0 + (A sin φ - B (1 - cos φ)) / θ``; with ``u = tan(φ/2)`` that is the quadratic
``(c0 θ - 2B) u² + 2A u + c0 θ = 0``, solved in the cancellation-free form. Stages turning more than 90° are
cut into equal sub-arcs so that ``u`` stays single-valued. A stage that meets a wall stops there (the bumper trips,
or a blocked wheel stalls), a hair short of the contact, so the cart never enters a wall. Only the drive stage's
contact is a bump (the paper's: the bumper's switch closes as the cart drives into a wall; on the drive's slight
arc the body's inner side can meet a box's corner first, which counts too: 0.22% of bumps on the ``obstacles``
map, none where no corner juts into the room); the turn's and the back-up's stop the cart unsensed and are
recorded apart (``LATEST_*``).

What the robot logs are encoder ticks: wheel rotation (not ground travel) in units of 0.0675 in, rounded. Ground
travel differs by a small per-stage wheel slip. At a bump the wheels can slip badly, unseen by the encoders (the
paper: "errors between bumps tend to be either very small or very large"): on a near head-on hit the bumper may
flatten against the wall (the cart turns square to it), on a glancing hit it may slide (the cart turns towards
parallel); see :class:`CartModel`.

State lives in a ``(rows, N_STATE)`` float64 array with the column constants below, parameters in one packed
vector, per-cycle random numbers in :class:`polyenvs.core.streams.RowStreams` blocks, so a batch of carts steps
in one compiled call.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from polyenvs.bumper.odometry import TICK_CM, odometry_step
from polyenvs.core.geometry2d import point_segment_distance_sq
from polyenvs.core.jit import njit
from polyenvs.core.parameters import check_parameters, documented, parameter, parameter_ranges

__all__ = ["CART_PARAMETER_RANGES", "DRAWS_PER_CYCLE", "N_STATE", "CartModel", "cycle_row", "max_ticks", "place_row"]

# State columns. True pose, dead-reckoned pose (nominal odometry from the true start), per-episode motor mismatch
# and true wheel base, then what the last cycle did.
X, Y, HEADING, DR_X, DR_Y, DR_HEADING, MISMATCH, BASE = range(8)
# The last bump's contact: where the bumper met a wall at the end of a drive stage (the wall's row, the fraction
# along it).
BUMP, CONTACT_X, CONTACT_Y, CONTACT_SEG, CONTACT_ALONG = range(8, 13)
BUMP_X, BUMP_Y, BUMP_HEADING = range(13, 16)  # true pose when the drive stage ended (at the bump)
TURN_X, TURN_Y = range(16, 18)  # position after the turn, for rendering paths
BIG_SLIP = 18  # 1 if the bump made the cart slip (flatten or slide)
TICKS = 19  # 6 columns: left, right of turn, drive, back-up
TURN_HEADING = 25  # heading after the turn (with TURN_X, TURN_Y: the pose the drive stage started from)
SLIP_X, SLIP_Y, SLIP_HEADING = range(26, 29)  # pose after the bump's slip (the back-up's start; the bump pose if none)
# The latest contact of any stage: the turn and the back-up stall against a wall too, unsensed (no switch closes), and
# the back-up's follows the bump's. BumperCartExplore-v0 and -v1 credit this wall (kept for their results).
LATEST_X, LATEST_Y, LATEST_SEG = range(29, 32)
N_STATE = 32

# Packed parameters.
(P_TICK, P_BASE, P_FRONT, P_HALF, P_REAR, P_BACKUP, P_DRIVE, P_SLIP, P_SNAP_P, P_SNAP_MAX, P_SLIDE_P,
 P_SLIDE_MAX) = range(12)  # fmt: skip
#: Standard normals a cart draws per cycle: wheel slip (2 per stage), two uniforms and one spare for the bump slip.
DRAWS_PER_CYCLE = 9
#: A stage stops this many cm (of its fastest-moving body point) short of a contact.
_BACKOFF_CM = 1e-6
#: A point this close to a line (cm) is on it: rounding may have put it a hair past the line.
_ON_LINE_CM = 1e-9
_INF = math.inf
#: Slack of the swept-region test that skips walls a motion cannot reach (cm): far above rounding, so a skipped wall
#: is one that would never have been hit.
_NEAR_MARGIN_CM = 1.0
#: Factor on the bound of how far a moving point's distance to a line changes (:func:`_crossing`).
_BOUND_SLACK = 1.01
#: Walls whose nearness one motion's contact search keeps in a bit mask (:func:`_near_mask`).
_MASK_WALLS = 64

#: Tyres add this much to the wheel base for the cart's width (the feasibility study's 6.0 cm base, 7.4 cm wide).
TYRE_WIDTH_CM = 1.4
#: Per-episode draws are cut at this many standard deviations, so no reachable state is unphysical.
_DRAW_LIMIT_SD = 4.0


_HIT_6 = "the paper's hit 6: the bumper flattens against the wall, the cart turns square to it, unseen"


@documented
@dataclass(frozen=True)
class CartModel:
    """The cart's geometry and error model (cm, degrees). Paper values where it gives them, else *ours*.

    {parameters}

    The wheel base plus 1.4 cm of tyres must fit under the bumper (it covers the cart's whole profile). One tick of
    wheel difference turns the default cart 1.64 degrees. Equal power drives an arc (``mismatch_sd``); a hit within
    ``snap_max_deg`` of head-on flattens the bumper with probability ``snap_prob``, a more glancing one slides
    towards parallel by up to ``slide_max_deg`` with probability ``slide_prob``.
    """

    wheel_base_cm: float = parameter(6.0, 3.0, 20.0, "cm", "ours (the paper gives none): 7.4 cm wide with tyres")
    bumper_width_cm: float = parameter(3.0 * 2.54, 4.0, 20.0, "cm", "paper: the 3-inch bumper; the body's width")
    bumper_offset_cm: float = parameter(7.0, 3.0, 20.0, "cm", "ours: bumper ahead of the axle")
    rear_cm: float = parameter(5.0, 1.0, 20.0, "cm", "ours: body behind the axle")
    backup_cm: float = parameter(6.0, 1.0, 30.0, "cm", "ours: the back-up stage's travel, 35 ticks")
    max_drive_cm: float = parameter(300.0, 10.0, 1000.0, "cm", "ours: the drive stage ends here if nothing is hit")
    mismatch_sd: float = parameter(
        0.02, 0.0, 0.1, "", 'ours: per-episode relative motor speed difference (paper: "not terribly well matched")'
    )
    wheel_base_sd: float = parameter(
        0.02, 0.0, 0.1, "", "ours: per-episode error of the true wheel base (paper: hard to measure, thick tyres)"
    )
    slip_sd: float = parameter(0.01, 0.0, 0.1, "", "ours: per-stage, per-wheel slip against the encoders")
    snap_prob: float = parameter(0.3, 0.0, 1.0, "", f"ours: {_HIT_6}")
    snap_max_deg: float = parameter(20.0, 0.0, 45.0, "deg", "ours: the most off head-on a flattening hit is")
    slide_prob: float = parameter(0.15, 0.0, 1.0, "", "ours: a more glancing hit slides towards parallel")
    slide_max_deg: float = parameter(30.0, 0.0, 90.0, "deg", "ours: the most a slide turns the cart")

    def __post_init__(self):
        check_parameters(self)
        if self.wheel_base_cm + TYRE_WIDTH_CM > self.bumper_width_cm:
            raise ValueError(
                f"wheel_base_cm {self.wheel_base_cm:g} plus {TYRE_WIDTH_CM} cm of tyres is wider than the bumper "
                f"({self.bumper_width_cm:g} cm): the bumper must cover the cart's whole profile"
            )

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def circumradius_cm(self) -> float:
        """The farthest body point from the axle centre."""
        return math.hypot(max(self.bumper_offset_cm, self.rear_cm), self.bumper_width_cm / 2)

    def packed(self) -> np.ndarray:
        return np.array([
            TICK_CM, self.wheel_base_cm, self.bumper_offset_cm, self.bumper_width_cm / 2, self.rear_cm,
            self.backup_cm, self.max_drive_cm, self.slip_sd, self.snap_prob, math.radians(self.snap_max_deg),
            self.slide_prob, math.radians(self.slide_max_deg),
        ])  # fmt: skip

    def draw_episode(self, rng: np.random.Generator) -> tuple[float, float]:
        """This episode's motor mismatch and true wheel base (two normals from ``rng``, cut at 4 sd)."""
        # Clipped as Python floats: the same numbers as np.clip's, without its call's cost (a vector env's resets).
        z_mismatch, z_base = (min(max(z, -_DRAW_LIMIT_SD), _DRAW_LIMIT_SD) for z in rng.standard_normal(2).tolist())
        return self.mismatch_sd * z_mismatch, self.wheel_base_cm * (1.0 + self.wheel_base_sd * z_base)


#: Physical parameters: (low, high) plausible range (from the declarations above); outside it: ValueError.
CART_PARAMETER_RANGES = parameter_ranges(CartModel)


def max_ticks(model: CartModel) -> int:
    """A bound on any stage's tick count (the observation space's bound)."""
    longest = max(model.max_drive_cm, model.backup_cm, math.pi * model.wheel_base_cm / 2)
    return int(math.ceil(longest * (1.0 + _DRAW_LIMIT_SD * 0.1 / 2) / TICK_CM)) + 1


@njit(cache=True)
def _line_crossings(c0, a, b, theta):
    """The two ``t`` at which the signed distance ``c0`` from the segment's line, moving at rate ``a`` (and with
    ``b = n . w``) through angle ``theta``, is zero (:func:`_crossing`); ``inf`` for a root that does not exist."""
    r0, r1 = _INF, _INF
    if theta == 0.0:
        if a != 0.0:
            r0 = -c0 / a
    else:
        qa, qb, qc = c0 * theta - 2.0 * b, 2.0 * a, c0 * theta
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return _INF, _INF
        q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
        if q != 0.0:
            r0 = 2.0 * math.atan(qc / q) / theta
        if qa != 0.0:
            r1 = 2.0 * math.atan(q / qa) / theta
    return r0, r1


@njit(cache=True)
def _crossing(point, w, theta, segment, outward, horizon):
    """First ``t`` in [0, 1] at which ``point = (px, py)`` (moving with ``w = (wx, wy)`` through angle ``theta``, as
    in the module docstring) enters across ``segment = (qx, qy, ex, ey)``, from ``q`` to ``q + e``, from its outer
    side; ``inf`` if it does not, and possibly when it does only after ``horizon`` (the caller's earliest contact so
    far, which a later one cannot beat). ``outward``: +1 if the outer side (free space for a wall, outside the body
    for a body edge) is left of ``e``, -1 if right.

    Only the direction of the crossing against that fixed outer side decides, never the side the point starts
    on: a point that first crosses the segment's line beyond the segment's end (round a wall corner that juts
    into the room) and then crosses back through the segment itself enters the wall there. A point on the line
    (within ``_ON_LINE_CM``, a rounding error either way) over the segment enters at ``t = 0`` if it moves in."""
    px, py = point
    wx, wy = w
    qx, qy, ex, ey = segment
    nx, ny = -ey * outward, ex * outward  # the normal to the outer side
    c0 = nx * (px - qx) + ny * (py - qy)  # the signed distance (times |e|): positive outside
    a = -nx * wy + ny * wx  # n . J w: its rate at t = 0
    b = nx * wx + ny * wy  # n . w
    length_sq = ex * ex + ey * ey
    on_line = c0 <= 0.0 and c0 * c0 < _ON_LINE_CM * _ON_LINE_CM * length_sq
    if on_line and (a < 0.0 or (a == 0.0 and theta * b > 0.0)):
        along = ((px - qx) * ex + (py - qy) * ey) / length_sq
        if -1e-12 <= along <= 1.0 + 1e-12:
            return 0.0  # touching and moving in (the second derivative decides when the first is zero)
    # Up to t = horizon the distance moves at most |a| t + |b theta| t^2 / 2 from c0 (|sin phi| <= |phi|,
    # 1 - cos phi <= phi^2 / 2): a point that stays clear of the line (with 1% to spare, far above rounding) cannot
    # cross it before the horizon, so the roots (which would all come later, or never) are not solved for.
    if abs(c0) > _BOUND_SLACK * horizon * (abs(a) + 0.5 * abs(b * theta) * horizon):
        return _INF
    r0, r1 = _line_crossings(c0, a, b, theta)
    best = _INF
    for t in (r0, r1):
        if not (0.0 <= t <= 1.0) or t >= best:
            continue
        phi = t * theta
        if a * math.cos(phi) - b * math.sin(phi) >= 0.0:
            continue  # leaving towards the outer side, or grazing the line
        if theta == 0.0:
            sa, ka = t, 0.0
        else:
            sa, ka = math.sin(phi) / theta, (1.0 - math.cos(phi)) / theta
        hx, hy = px - sa * wy - ka * wx, py + sa * wx - ka * wy
        along = ((hx - qx) * ex + (hy - qy) * ey) / length_sq
        if -1e-12 <= along <= 1.0 + 1e-12:
            best = t
    return best


@njit(cache=True)
def _wall_near(chord, reach, walls, k) -> bool:
    """Whether a motion whose axle moves along ``chord = (x0, y0, x1, y1)`` can touch real wall ``k`` of ``walls``:
    every body point stays within the body's reach of the axle, and the axle within a quarter of ``|s theta|`` of
    its path's chord (an arc of at most 90 degrees lies within an eighth of it), so a wall farther than their sum
    and a margin, ``reach``, from the chord is never touched, by a corner or by one of its vertices.

    Bounding boxes farther apart than ``reach`` (and a hair, far above rounding) settle most walls before the exact
    test."""
    if walls[k, 5] == 0.0:
        return False
    x0, y0, x1, y1 = chord
    qx0, qy0 = walls[k, 0], walls[k, 1]
    qx1, qy1 = qx0 + walls[k, 2], qy0 + walls[k, 3]
    gap = reach * (1.0 + 1e-9) + 1e-9
    if (
        min(qx0, qx1) - max(x0, x1) > gap
        or min(x0, x1) - max(qx0, qx1) > gap
        or min(qy0, qy1) - max(y0, y1) > gap
        or min(y0, y1) - max(qy0, qy1) > gap
    ):
        return False
    return _segments_within(chord, (qx0, qy0, qx1, qy1), reach)


@njit(cache=True)
def _segments_within(p, q, reach) -> bool:
    """Whether segments ``p`` and ``q`` (end points ``(x0, y0, x1, y1)``) come within ``reach`` of each other."""
    px, py, px1, py1 = p
    qx, qy, qx1, qy1 = q
    mx, my, ex, ey = px1 - px, py1 - py, qx1 - qx, qy1 - qy
    d1 = ex * (py - qy) - ey * (px - qx)
    d2 = ex * (py1 - qy) - ey * (px1 - qx)
    d3 = mx * (qy - py) - my * (qx - px)
    d4 = mx * (qy1 - py) - my * (qx1 - px)
    if d1 * d2 <= 0.0 and d3 * d4 <= 0.0:
        return True  # they cross (or touch, or lie on one line: never skipped)
    r2 = reach * reach
    return (
        point_segment_distance_sq(px, py, q) <= r2
        or point_segment_distance_sq(px1, py1, q) <= r2
        or point_segment_distance_sq(qx, qy, p) <= r2
        or point_segment_distance_sq(qx1, qy1, p) <= r2
    )


@njit(inline="always")
def _body_corner(i, front, half, rear):
    """Body corner ``i`` in the cart's frame (x ahead, y left of the axle): front right, front left, rear left, rear
    right; corner ``i`` to ``i + 1`` is a body edge."""
    return (front if i < 2 else -rear), (half if i == 1 or i == 2 else -half)


@njit(cache=True)
def _first_contact(x, y, h, a, b, d, params, walls):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """First contact of the body moving by wheel travels ``(a, b)`` on base ``d`` from ``(x, y, h)``:
    ``(t, segment, contact x, contact y)``; ``t = inf`` and segment -1 when the motion is free."""
    x1, y1, _ = odometry_step(x, y, h, a, b, d)
    return _contact((x, y, h), a, b, d, (x1, y1), params, walls)


@njit(cache=True)
def _contact(start, a, b, d, end, params, walls):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """:func:`_first_contact` from pose ``start = (x, y, h)`` of the motion whose axle ends at ``end = (x1, y1)``.

    Every body corner against every wall the motion can reach (:func:`_wall_near`), then every wall's start vertex
    (every polygon is closed: the starts are all the vertices) against every body edge; the earliest contact wins,
    a tie the first found. Each crossing is solved only up to the earliest contact found so far
    (:func:`_crossing`'s horizon), and the front corners, the likeliest to hit first in the drive, come first."""
    x, y, h = start
    theta, s = (b - a) / d, 0.5 * (a + b)
    c, sn = math.cos(h), math.sin(h)
    front, half, rear = params[P_FRONT], params[P_HALF], params[P_REAR]
    chord = (x, y, end[0], end[1])
    reach = math.hypot(max(front, rear), half) + 0.25 * abs(s * theta) + _NEAR_MARGIN_CM
    near = _near_mask(chord, reach, walls)
    best, seg, cx, cy = _INF, -1, 0.0, 0.0
    for i in range(4):  # body corners: front right, front left, rear left, rear right
        lx, ly = _body_corner(i, front, half, rear)
        px, py = x + lx * c - ly * sn, y + lx * sn + ly * c
        wx, wy = theta * (px - x) + s * sn, theta * (py - y) - s * c
        for k in range(walls.shape[0]):
            if not _is_near(near, k, chord, reach, walls):
                continue
            wall = (walls[k, 0], walls[k, 1], walls[k, 2], walls[k, 3])
            t = _crossing((px, py), (wx, wy), theta, wall, walls[k, 5], min(best, 1.0))  # column 5: free space's side
            if t < best:
                phi = t * theta
                sa = t if theta == 0.0 else math.sin(phi) / theta
                ka = 0.0 if theta == 0.0 else (1.0 - math.cos(phi)) / theta
                best, seg, cx, cy = t, k, px - sa * wy - ka * wx, py + sa * wx - ka * wy
    for k in range(walls.shape[0]):  # wall vertices crossing body edges (in the cart's frame: the reverse arc)
        if not _is_near(near, k, chord, reach, walls):
            continue
        vx, vy = walls[k, 0], walls[k, 1]
        wx, wy = -theta * (vx - x) - s * sn, -theta * (vy - y) + s * c
        for i in range(4):
            l0x, l0y = _body_corner(i, front, half, rear)
            l1x, l1y = _body_corner((i + 1) % 4, front, half, rear)
            rx, ry = x + l0x * c - l0y * sn, y + l0x * sn + l0y * c
            ex, ey = (l1x - l0x) * c - (l1y - l0y) * sn, (l1x - l0x) * sn + (l1y - l0y) * c
            outward = math.copysign(1.0, ey * (x - rx) - ex * (y - ry))  # outside the body: opposite the axle
            t = _crossing((vx, vy), (wx, wy), -theta, (rx, ry, ex, ey), outward, min(best, 1.0))
            if t < best:
                best, seg, cx, cy = t, k, vx, vy
    return best, seg, cx, cy


@njit(cache=True)
def _near_mask(chord, reach, walls):
    """Bit ``k`` set where wall ``k`` (of the first 64) is near the motion (:func:`_wall_near`): worked out once for
    the eight passes over the walls, without an array allocated per motion."""
    mask = np.uint64(0)
    for k in range(min(walls.shape[0], _MASK_WALLS)):
        if _wall_near(chord, reach, walls, k):
            mask |= np.uint64(1) << np.uint64(k)
    return mask


@njit(inline="always")
def _is_near(mask, k, chord, reach, walls) -> bool:
    """Whether wall ``k`` is near the motion: its bit of ``mask``, or the test itself past the first 64 walls."""
    if k < _MASK_WALLS:
        return (mask >> np.uint64(k)) & np.uint64(1) != np.uint64(0)
    return _wall_near(chord, reach, walls, k)


@njit(cache=True)
def _move(row, a, b, d, params, walls):
    """Move the cart of ``row`` (its X, Y, HEADING) by wheel ground travels ``(a, b)`` on true base ``d``, stopping
    short of the first contact. Returns ``(fraction done, segment hit or -1, contact x, contact y)``."""
    theta = (b - a) / d
    pieces = max(1, int(math.ceil(abs(theta) / (0.5 * math.pi))))
    pa, pb = a / pieces, b / pieces
    done = 0.0
    for _ in range(pieces):
        end = odometry_step(row[X], row[Y], row[HEADING], pa, pb, d)
        t, seg, cx, cy = _contact((row[X], row[Y], row[HEADING]), pa, pb, d, end[:2], params, walls)
        if seg < 0:
            row[X], row[Y], row[HEADING] = end
            done += 1.0
            continue
        # Travel of the fastest body point per unit t: the axle's plus the spin times the body's reach.
        lever = abs(0.5 * (pa + pb)) + abs((pb - pa) / d) * (params[P_FRONT] + params[P_HALF] + params[P_REAR])
        t = max(0.0, t - _BACKOFF_CM / max(lever, 1e-12))
        row[X], row[Y], row[HEADING] = odometry_step(row[X], row[Y], row[HEADING], t * pa, t * pb, d)
        return (done + t) / pieces, seg, cx, cy
    return 1.0, -1, 0.0, 0.0


@njit(cache=True)
def _uniform(z):
    """A standard normal draw mapped to a uniform in (0, 1) (its distribution function)."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


@njit(cache=True)
def _stage(row, k, a_cmd, b_cmd, z_a, z_b, params, walls):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """One logged stage: wheels commanded to rotate ``(a_cmd, b_cmd)`` cm; ground travel has per-wheel slip. Logs
    the rounded ticks of the rotation done, dead-reckons them, records a contact as the latest; returns the contact
    ``(segment or -1, x, y)``."""
    slip = params[P_SLIP]
    ga = a_cmd * (1.0 + slip * min(max(z_a, -4.0), 4.0))
    gb = b_cmd * (1.0 + slip * min(max(z_b, -4.0), 4.0))
    done, seg, cx, cy = _move(row, ga, gb, row[BASE], params, walls)
    tick = params[P_TICK]
    left, right = np.rint(done * a_cmd / tick), np.rint(done * b_cmd / tick)
    row[TICKS + 2 * k], row[TICKS + 2 * k + 1] = left, right
    row[DR_X], row[DR_Y], row[DR_HEADING] = odometry_step(
        row[DR_X], row[DR_Y], row[DR_HEADING], left * tick, right * tick, params[P_BASE]
    )
    if seg >= 0:
        row[LATEST_X], row[LATEST_Y], row[LATEST_SEG] = cx, cy, seg
    return seg, cx, cy


@njit(cache=True)
def _bump_slip(row, seg, u_kind, u_amount, params, walls):
    """The heavy tail: a hit may flatten the bumper (near head-on) or slide (glancing), turning the cart unseen."""
    w = walls[seg]
    nx, ny = -w[3], w[2]
    if nx * (row[X] - w[0]) + ny * (row[Y] - w[1]) < 0.0:
        nx, ny = -nx, -ny
    norm = math.hypot(nx, ny)
    nx, ny = nx / norm, ny / norm
    hx, hy = math.cos(row[HEADING]), math.sin(row[HEADING])
    incidence = math.atan2(-nx * hy + ny * hx, -nx * hx - ny * hy)  # heading relative to "into the wall"
    if abs(incidence) < params[P_SNAP_MAX]:
        turn = -incidence if u_kind < params[P_SNAP_P] else 0.0
    else:
        turn = math.copysign(u_amount * params[P_SLIDE_MAX], incidence) if u_kind < params[P_SLIDE_P] else 0.0
    if turn == 0.0:
        return 0.0
    half = 0.5 * turn * row[BASE]
    _move(row, -half, half, row[BASE], params, walls)
    return 1.0


@njit(cache=True)
def cycle_row(row, turn, draws, params, walls):
    """One cycle of one cart (a ``(N_STATE,)`` state row): turn by ``turn`` rad, drive to the bump, back up.

    ``draws``: ``DRAWS_PER_CYCLE`` standard normals. The controller aims the turn with the nominal wheel base
    (wheels opposite until their tick difference says ``turn``), so mismatch and the true base make it imperfect.
    """
    m = row[MISMATCH]
    slow, fast = 1.0 - 0.5 * m, 1.0 + 0.5 * m
    spin = 0.5 * turn * params[P_BASE]
    _stage(row, 0, -spin * slow, spin * fast, draws[0], draws[1], params, walls)
    row[TURN_X], row[TURN_Y], row[TURN_HEADING] = row[X], row[Y], row[HEADING]
    drive = params[P_DRIVE]
    # The paper's bump: the drive stage ends with the bumper's switch closed. The turn's and the back-up's contacts
    # stop the cart (physics) but close no switch: they never become the bump's contact.
    seg, cx, cy = _stage(row, 1, drive * slow, drive * fast, draws[2], draws[3], params, walls)
    row[BUMP] = 1.0 if seg >= 0 else 0.0
    row[BUMP_X], row[BUMP_Y], row[BUMP_HEADING] = row[X], row[Y], row[HEADING]
    row[BIG_SLIP] = 0.0
    if seg >= 0:
        w = walls[seg]
        row[CONTACT_X], row[CONTACT_Y], row[CONTACT_SEG] = cx, cy, seg
        row[CONTACT_ALONG] = ((cx - w[0]) * w[2] + (cy - w[1]) * w[3]) * w[4]
        row[BIG_SLIP] = _bump_slip(row, seg, _uniform(draws[6]), _uniform(draws[7]), params, walls)
    row[SLIP_X], row[SLIP_Y], row[SLIP_HEADING] = row[X], row[Y], row[HEADING]
    backup = params[P_BACKUP]
    _stage(row, 2, -backup * slow, -backup * fast, draws[4], draws[5], params, walls)
    # Headings stay in [-pi, pi) so that nothing drifts towards precision loss over long episodes.
    row[HEADING] = (row[HEADING] + math.pi) % (2.0 * math.pi) - math.pi
    row[DR_HEADING] = (row[DR_HEADING] + math.pi) % (2.0 * math.pi) - math.pi
    row[BUMP_HEADING] = (row[BUMP_HEADING] + math.pi) % (2.0 * math.pi) - math.pi
    row[TURN_HEADING] = (row[TURN_HEADING] + math.pi) % (2.0 * math.pi) - math.pi
    row[SLIP_HEADING] = (row[SLIP_HEADING] + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def place_row(row, pose, mismatch, wheel_base):
    """Start a cart at ``pose`` (x, y, heading rad; an array) with dead reckoning at the true pose (compiled: a vector
    env places hundreds of carts at once)."""
    x, y, heading = pose[0], pose[1], pose[2]
    row[:] = 0.0
    row[X], row[Y], row[HEADING] = x, y, heading
    row[DR_X], row[DR_Y], row[DR_HEADING] = x, y, heading
    row[BUMP_X], row[BUMP_Y], row[BUMP_HEADING] = x, y, heading
    row[TURN_X], row[TURN_Y], row[TURN_HEADING] = x, y, heading
    row[SLIP_X], row[SLIP_Y], row[SLIP_HEADING] = x, y, heading
    row[MISMATCH], row[BASE] = mismatch, wheel_base
    row[CONTACT_SEG] = row[LATEST_SEG] = -1.0
