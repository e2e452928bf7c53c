"""Batched Buckybot simulation core: tipping on the honeycomb lattice, wall contact and range sensing.

State per robot (batch axis first): position of the contact-face centre (cm), resting face, the *motion frame*
(which physical edge of the resting face is the frame's tip direction 0, and that direction's world azimuth),
plus the dead-reckoned position and heading the robot itself computes from its actuator sequence.

The motion frame. Observations and actions live in the resting face's frame, with the three tip directions at
azimuths 0°, 120°, 240° (counter-clockwise from above). Direction 0 is the edge the robot last tipped over, i.e.
tipping 0 goes back where it came from; after a reset it is the edge opposite the face's first-lettered actuator.
Tip ``j`` rotates the frame by ``120° j + 180°`` (plus the heading noise), whatever the faces involved, so a policy
that remembers anything can carry it from one frame to the next. ``info`` publishes the frame's world heading, the
resting face and the actuator each action extends.

Packed state. Everything a step reads or writes about a robot is one row of ``BuckybotSimulator.state``
(float64, columns named by the constants below), and the compiled kernels take the simulator's arrays as one tuple
``sim`` (:data:`SIM_ARRAYS`: state, walls, parameters, draws, observation rows, scratch), which numba unpacks for
free, instead of twenty arguments. ``advance_rows(actions, sim)`` (a step of every robot) and
``first_sense_row(b, sim)`` (a reset) are called by the family's compiled step and reset
(:func:`polyenvs.buckybot.env.step_task` and ``reset_task``), which score the task's rows and write their
observations in the same call.

Walls. A tip is allowed when its mean landing point keeps the body ``body_radius_cm`` off every wall and the
straight motion there crosses no wall (the action mask is exactly this test). The noisy landing is used when its
own motion crosses no wall and leaves the centre at least half the body radius from every wall; otherwise the
body's contact stops it at the mean landing point. So no accepted parameter lets the centre pass through a wall.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.sensors import measure_one
from polyenvs.core import libm
from polyenvs.core.columns import indices, spans
from polyenvs.core.geometry2d import (
    SegmentTable,
    crossings,
    first_hits,
    nearest_point,
    nearest_squared,
    ray_distance,
    segment_crosses,
)
from polyenvs.core.jit import njit
from polyenvs.core.parameters import check_parameters, documented, parameter, parameter_ranges
from polyenvs.core.streams import RowStreams

__all__ = [
    "BASE_METRICS",
    "GROUND_TRUTH_STRUCTURE",
    "NORMALS_PER_STEP",
    "SENSOR_OBSERVATION_STRUCTURE",
    "SIM_ARRAYS",
    "TIP_ANGLES_RAD",
    "BuckybotParams",
    "BuckybotSimulator",
    "PARAMETER_RANGES",
]

#: Frame azimuths of the three tip directions.
TIP_ANGLES_RAD = np.radians([0.0, 120.0, 240.0])
#: Standard normals a robot consumes per step: 3 for the tip (forward, lateral, heading), 6 for the sensors.
NORMALS_PER_STEP = 9
_TWO_PI = 2.0 * np.pi
_COS_ELEVATION = float(libm.cos(geo.SENSOR_ELEVATION_RAD))
_SENSOR_OFFSET = float(geo.SENSOR_HORIZONTAL_OFFSET_CM)
_BEAM_COS = libm.cos(geo.SENSOR_AZIMUTHS_RAD)
_BEAM_SIN = libm.sin(geo.SENSOR_AZIMUTHS_RAD)
_TIP_COS = libm.cos(TIP_ANGLES_RAD)
_TIP_SIN = libm.sin(TIP_ANGLES_RAD)
_NEIGHBOR = np.ascontiguousarray(geo.NEIGHBOR, dtype=np.int64)
_BACK_EDGE = np.ascontiguousarray(geo.BACK_EDGE, dtype=np.int64)

# Columns of ``BuckybotSimulator.state``.
X, Y, HEADING, FACE, EDGE0, DR_X, DR_Y, DR_HEADING = range(8)
READING = 8  # 6 columns: the sensor's reading in cm, nan where invalid
TOO_CLOSE = 14  # 6: 1 where the reading did not settle
NO_RETURN = 20  # 6: 1 where nothing was seen within range
ALLOWED = 26  # 3: 1 where a tip would not hit a wall
FOOT_X, FOOT_Y, WALL_SEGMENT = 29, 30, 31
BLOCKED, STEPS, BLOCKED_TIPS, OSCILLATIONS, LAST_TIP_MOVED = 32, 33, 34, 35, 36
# Cosine and sine of HEADING (from the last sense) and DR_HEADING (turned by the fixed mean turn of each tip),
# kept so that a tip needs no trigonometry of its own.
HEADING_COS, HEADING_SIN, DR_COS, DR_SIN = 37, 38, 39, 40
#: The ground truth ``info["ground_truth"]`` publishes, in the units it publishes: name -> size. ``pose`` and
#: ``dead_reckoned_pose`` are x, y (cm) and the heading of frame direction 0 (deg); ``tip_directions_deg`` the world
#: azimuths of the three actions; ``true_range_cm`` the slant range along each upper beam to the first wall (inf if
#: none); ``wall_distance_cm`` the distance from the centre to the nearest wall. The state keeps them contiguous, in
#: this order, so one copy of the block is the whole entry.
GROUND_TRUTH = {"pose": 3, "dead_reckoned_pose": 3, "tip_directions_deg": 3, "true_range_cm": 6, "wall_distance_cm": 1}
#: The same as name -> (start, stop) indices of ``info["ground_truth"]``.
GROUND_TRUTH_STRUCTURE = spans(GROUND_TRUTH)
INFO_START = 41
POSE_INFO, DR_POSE_INFO, TIP_DIRECTIONS, TRUE_RANGE, WALL_DISTANCE = (
    INFO_START + GROUND_TRUTH_STRUCTURE[name][0] for name in GROUND_TRUTH
)
INFO_STOP = INFO_START + GROUND_TRUTH_STRUCTURE["wall_distance_cm"][1]
STATE_COLUMNS = INFO_STOP

# Entries of ``BuckybotSimulator.params``.
P_FORWARD, P_FORWARD_SD, P_LATERAL, P_LATERAL_SD, P_TURN_SD, P_BODY_RADIUS, P_RANGE_NOISE = range(7)
P_MEAN_OFFSETS = 7  # 6: (3, 2) mean displacement of each tip in the motion frame
P_FRAME_TURN = 13  # 3: mean frame rotation of each tip (rad)
P_TURN_COS, P_TURN_SIN = 16, 19  # 3 each: its cosine and sine
P_STEP_REACH = 22  # length of the mean tip displacement (the same for the three tips)
N_PARAMS = 23

# Rows of the step's scratch array ``(SCRATCH_ROWS, 6 * batch)``: flat query arrays for the batched geometry
# kernels. Rays: 6 per robot. Centres: 1 per robot. Landings and motions: 3 per robot near a wall (compacted; the
# robot of each group is in ``groups[1]``), or 1 per tipping robot near a wall (``groups[0]``). Tip proposals.
R_OX, R_OY, R_DX, R_DY, R_T = range(5)
PT_X, PT_Y, PT_D2, PT_K = range(5, 9)
C_X, C_Y, C_D2, C_K = range(9, 13)
MV_AX, MV_AY, MV_BX, MV_BY, MV_HIT = range(13, 18)
TIP_NX, TIP_NY, TIP_MX, TIP_MY, TIP_ACTIVE, TIP_SAFE = range(18, 24)
SCRATCH_ROWS = 24
# A query is skipped only when the triangle inequality settles it with this much to spare (cm).
_MARGIN_CM = 1e-6

#: The sensor part of every Buckybot observation (its first entries): name -> size. Ranges are reading /
#: 182.88 cm for valid readings (0 when too close, 1 when no return); too_close is 1 where the sensor did not
#: settle (< 30.48 cm), no_return 1 where nothing was seen within 182.88 cm, tip_failed 1 if the last tip was
#: blocked (the accelerometer reports the same face).
SENSOR_OBSERVATION = {"range": 6, "too_close": 6, "no_return": 6, "tip_failed": 1}
#: The same as name -> (start, stop) indices.
SENSOR_OBSERVATION_STRUCTURE = spans(SENSOR_OBSERVATION)
OBS_RANGE, OBS_TOO_CLOSE, OBS_NO_RETURN, OBS_TIP_FAILED = (
    SENSOR_OBSERVATION_STRUCTURE[name][0] for name in ("range", "too_close", "no_return", "tip_failed")
)
N_SENSOR_OBS = SENSOR_OBSERVATION_STRUCTURE["tip_failed"][1]

#: The arrays every compiled step and reset takes, as one tuple ``sim`` in this order: the packed state, the walls
#: ``(W, S, 6)``, the parameters, the draw blocks and cursors (:class:`polyenvs.core.streams.RowStreams`), the
#: observation rows (float32, the sensor part first), the step's scratch and its query groups.
SIM_ARRAYS = ("state", "walls", "params", "normals", "cursor", "obs", "scratch", "groups")
_SIM = indices(SIM_ARRAYS)
A_STATE, A_WALLS, A_PARAMS, A_NORMALS = _SIM["state"], _SIM["walls"], _SIM["params"], _SIM["normals"]
A_CURSOR, A_OBS, A_SCRATCH, A_GROUPS = _SIM["cursor"], _SIM["obs"], _SIM["scratch"], _SIM["groups"]

#: The metrics every Buckybot task reports: name -> the state column that counts it.
BASE_METRICS = {"blocked_tips": BLOCKED_TIPS, "oscillation_events": OSCILLATIONS}
_BASE_METRIC_STATE = tuple(BASE_METRICS.values())


_TEST_RESULTS = "paper, Test Results (Vicon, 10 repetitions of all 60 tips)"


@documented
@dataclass(frozen=True)
class BuckybotParams:
    """The robot: its tip model, range noise and body, the physical parameters every Buckybot id takes as keywords.

    A tip displaces the robot by ``step_forward_cm`` along the tip direction and ``step_lateral_cm`` to its right
    and turns it by ``heading_change_deg`` (counter-clockwise from above), each with its sd, uncorrelated; the
    defaults are the paper's Vicon measurements ("Test Results": 10 repetitions of all 60 tip combinations,
    forward 9.266 ± 0.105 cm, lateral -0.745 ± 0.149 cm, heading +0.31 ± 0.44°). ``noise_scale`` interpolates
    between the ideal lattice (0: 9.129 cm straight steps, no spread) and that model (1): both the spread and the
    systematic offsets scale, so 0 is the exact honeycomb. :meth:`packed` is what the simulator runs.

    {parameters}
    """

    noise_scale: float = parameter(1.0, 0.0, 1.0, "", "tipping noise: 0 = the ideal lattice, 1 = the paper's")
    range_noise_scale: float = parameter(1.0, 0.0, 5.0, "", "multiplies the eq. 6 range noise sd")
    step_forward_cm: float = parameter(9.266, 5.0, 15.0, "cm", f"forward step per tip, {_TEST_RESULTS}")
    step_forward_sd_cm: float = parameter(0.105, 0.0, 2.0, "cm", f"its sd, {_TEST_RESULTS}")
    step_lateral_cm: float = parameter(-0.745, -3.0, 3.0, "cm", f"lateral step per tip, {_TEST_RESULTS}")
    step_lateral_sd_cm: float = parameter(0.149, 0.0, 2.0, "cm", f"its sd, {_TEST_RESULTS}")
    heading_change_deg: float = parameter(0.31, -10.0, 10.0, "deg", f"heading change per tip, {_TEST_RESULTS}")
    heading_sd_deg: float = parameter(0.44, 0.0, 10.0, "deg", f"its sd, {_TEST_RESULTS}")
    body_radius_cm: float = parameter(geo.BODY_RADIUS_CM, 6.5, 26.0, "cm", "contact radius (the 26 cm diameter)")

    def __post_init__(self):
        check_parameters(self)

    def packed(self) -> np.ndarray:
        """The simulator's parameter vector (entries ``P_*``): the tip model scaled by ``noise_scale``, the range
        noise and the body radius."""
        s, ideal = self.noise_scale, geo.STEP_LENGTH_CM
        forward, lateral = ideal + s * (self.step_forward_cm - ideal), s * self.step_lateral_cm
        offsets = _mean_offsets(forward, lateral)
        turn = TIP_ANGLES_RAD + np.pi + np.radians(s * self.heading_change_deg)
        params = np.zeros(N_PARAMS)
        params[P_FORWARD], params[P_FORWARD_SD] = forward, s * self.step_forward_sd_cm
        params[P_LATERAL], params[P_LATERAL_SD] = lateral, s * self.step_lateral_sd_cm
        params[P_TURN_SD] = np.radians(s * self.heading_sd_deg)
        params[P_BODY_RADIUS], params[P_RANGE_NOISE] = self.body_radius_cm, self.range_noise_scale
        params[P_MEAN_OFFSETS : P_MEAN_OFFSETS + 6] = offsets.ravel()
        params[P_FRAME_TURN : P_FRAME_TURN + 3] = turn
        params[P_TURN_COS : P_TURN_COS + 3], params[P_TURN_SIN : P_TURN_SIN + 3] = libm.cos(turn), libm.sin(turn)
        params[P_STEP_REACH] = float(np.hypot(*offsets[0]))
        return params


#: Physical parameters: (low, high) plausible range (from :class:`BuckybotParams`). Outside it: ValueError.
PARAMETER_RANGES = parameter_ranges(BuckybotParams)


def _mean_offsets(forward_cm: float, lateral_cm: float) -> np.ndarray:
    """(3, 2) mean displacement of each of the three tips in the motion frame."""
    c, s = _TIP_COS, _TIP_SIN
    # Forward along (c, s); "right" of the tip direction is (s, -c).
    return np.stack([forward_cm * c + lateral_cm * s, forward_cm * s - lateral_cm * c], axis=-1)


class BuckybotSimulator:
    """A batch of Buckybots on wall plans; every array has the batch on axis 0.

    Args:
        batch_size: number of robots.
        robot: the robots' parameters (tip model, range noise, body radius).

    Attributes:
        state: ``(batch_size, STATE_COLUMNS)`` packed robot state (see the column constants).
        walls: ``(W, S, 6)`` packed walls (:mod:`polyenvs.core.geometry2d`), W = 1 (shared) or ``batch_size``.
        streams: each row's random stream (:class:`polyenvs.core.streams.RowStreams`).
        observation: ``(batch_size, 19)`` float32, the sensor part of the observation after the last sense.
    """

    def __init__(self, batch_size: int, robot: BuckybotParams):
        self.batch_size = b = int(batch_size)
        self.params = robot.packed()
        self.state = np.zeros((b, STATE_COLUMNS))
        self.state[:, TRUE_RANGE : TRUE_RANGE + 6] = np.inf
        self.state[:, READING : READING + 6] = np.nan
        self.state[:, ALLOWED : ALLOWED + 3] = 1.0
        self.walls = np.zeros((1, 1, 6))
        self.streams = RowStreams(b, NORMALS_PER_STEP)
        self.observation = np.zeros((b, N_SENSOR_OBS), dtype=np.float32)
        self.scratch = np.zeros((SCRATCH_ROWS, 6 * b))
        # Robot of each compacted query group: tipping robots near a wall, robots near a wall, every robot.
        self.groups = np.zeros((3, b), dtype=np.int64)
        self.groups[2] = np.arange(b)

    def kernel_arrays(self, obs: np.ndarray) -> tuple:
        """The tuple ``sim`` (:data:`SIM_ARRAYS`) the compiled kernels take, with observation rows ``obs`` (the
        sensor part first); build it again after :meth:`set_walls`."""
        s = self.streams
        arrays = dict(state=self.state, walls=self.walls, params=self.params, normals=s.normals, cursor=s.cursor,
                      obs=obs, scratch=self.scratch, groups=self.groups)  # fmt: skip
        return tuple(arrays[name] for name in SIM_ARRAYS)

    # Named views of the packed state (writable where that makes sense).
    position = property(lambda self: self.state[:, X : Y + 1])
    heading = property(lambda self: self.state[:, HEADING])
    edge0 = property(lambda self: self.state[:, EDGE0].astype(np.int64))

    # --- state ------------------------------------------------------------------------------------------------
    def set_walls(self, walls: SegmentTable | np.ndarray) -> None:
        """Install walls: a ``SegmentTable`` or a packed ``(W, S, 6)`` array, W = 1 or the batch size."""
        packed = walls.packed if isinstance(walls, SegmentTable) else np.asarray(walls, dtype=np.float64)
        if packed.ndim != 3 or packed.shape[0] not in (1, self.batch_size) or packed.shape[2] != 6:
            raise ValueError(f"walls of shape {packed.shape} do not fit a batch of {self.batch_size}")
        self.walls = np.ascontiguousarray(packed)

    def place_one(self, row: int, position, face: int, heading: float) -> None:
        """:meth:`place` for one robot, in one compiled call (a vector env resets a few robots every step)."""
        _place_row(self.state, row, float(position[0]), float(position[1]), face, heading)

    def place(self, index, position, face, heading) -> None:
        """Put robots ``index`` at a pose (true and dead-reckoned pose agree at the start) and clear their records."""
        state = self.state
        state[index, X : Y + 1] = position
        state[index, DR_X : DR_Y + 1] = position
        state[index, FACE] = face
        state[index, EDGE0] = 0
        state[index, HEADING] = np.mod(heading, _TWO_PI)
        state[index, DR_HEADING] = state[index, HEADING]
        state[index, DR_COS], state[index, DR_SIN] = libm.cos(state[index, HEADING]), libm.sin(state[index, HEADING])
        state[index, BLOCKED : LAST_TIP_MOVED + 1] = 0.0

    # --- dynamics with explicit draws (analysis and tests) ----------------------------------------------------
    def tip(self, action: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Tip every robot in direction ``action`` (B,) ints in {0, 1, 2}; ``normals`` (B, 3) standard normals.

        A tip the action mask forbids is blocked: the robot stays put and knows it (its accelerometer still
        reports the same face). An action of -1 leaves that robot alone. Returns the (B,) blocked flags.
        """
        action = np.ascontiguousarray(action, dtype=np.int64)
        draws = np.zeros((self.batch_size, NORMALS_PER_STEP))
        draws[:, :3] = normals
        _tip_rows(action, draws, self.state, self.walls, self.params)
        return self.state[:, BLOCKED] > 0.5

    def sense(self, normals: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Range readings at the current pose for ``rows`` (default all), with ``normals`` ``(len(rows), 6)``."""
        rows = np.arange(self.batch_size) if rows is None else np.asarray(rows, dtype=np.int64)
        draws = np.zeros((len(rows), NORMALS_PER_STEP))
        draws[:, 3:] = normals
        _sense_rows(rows, draws, self.state, self.walls, self.params, self.observation)


@njit(cache=True)
def _place_row(state, b, x, y, face, heading):
    heading = wrap_angle(heading)
    state[b, X], state[b, Y], state[b, DR_X], state[b, DR_Y] = x, y, x, y
    state[b, FACE], state[b, EDGE0] = face, 0.0
    state[b, HEADING] = state[b, DR_HEADING] = heading
    state[b, DR_COS], state[b, DR_SIN] = math.cos(heading), math.sin(heading)
    for column in range(BLOCKED, LAST_TIP_MOVED + 1):
        state[b, column] = 0.0


@njit(cache=True)
def wrap_angle(angle):
    """``angle`` in [0, 2π) (cheaper than Python's float modulo, which numba reproduces exactly)."""
    return angle - _TWO_PI * math.floor(angle / _TWO_PI)


@njit(cache=True)
def dead_reckon(b, a, state, params):
    """The robot's own estimate after tip ``a`` succeeded: it replays the mean model (no trigonometry: the
    heading's cosine and sine turn by the tip's fixed mean turn)."""
    dc, ds = state[b, DR_COS], state[b, DR_SIN]
    mx, my = params[P_MEAN_OFFSETS + 2 * a], params[P_MEAN_OFFSETS + 2 * a + 1]
    state[b, DR_X] += dc * mx - ds * my
    state[b, DR_Y] += ds * mx + dc * my
    tc, ts = params[P_TURN_COS + a], params[P_TURN_SIN + a]
    state[b, DR_COS], state[b, DR_SIN] = dc * tc - ds * ts, ds * tc + dc * ts
    state[b, DR_HEADING] = wrap_angle(state[b, DR_HEADING] + params[P_FRAME_TURN + a])


@njit(cache=True)
def tip_row(b, a, state, walls, params, z):
    """Tip robot ``b`` in frame direction ``a`` with draws ``z[0:3]``; returns whether it was blocked."""
    blocked = state[b, ALLOWED + a] < 0.5
    if blocked:
        state[b, BLOCKED] = 1.0
        return True
    x, y, heading = state[b, X], state[b, Y], state[b, HEADING]
    hc, hs = math.cos(heading), math.sin(heading)
    c, s = hc * _TIP_COS[a] - hs * _TIP_SIN[a], hs * _TIP_COS[a] + hc * _TIP_SIN[a]  # the tip's direction
    forward = params[P_FORWARD] + params[P_FORWARD_SD] * z[0]
    lateral = params[P_LATERAL] + params[P_LATERAL_SD] * z[1]  # +lateral is to the right of the tip direction
    nx, ny = x + forward * c + lateral * s, y + forward * s - lateral * c
    mx, my = params[P_MEAN_OFFSETS + 2 * a], params[P_MEAN_OFFSETS + 2 * a + 1]
    if segment_crosses(x, y, nx, ny, walls) or nearest_point(nx, ny, walls)[0] < 0.5 * params[P_BODY_RADIUS]:
        nx, ny = x + hc * mx - hs * my, y + hs * mx + hc * my  # contact stops the body at the checked landing
    state[b, X], state[b, Y] = nx, ny
    state[b, HEADING] = wrap_angle(heading + params[P_FRAME_TURN + a] + params[P_TURN_SD] * z[2])
    dead_reckon(b, a, state, params)
    old, edge = int(state[b, FACE]), (int(state[b, EDGE0]) + a) % 3
    state[b, FACE] = _NEIGHBOR[old, edge]
    state[b, EDGE0] = _BACK_EDGE[old, edge]
    state[b, BLOCKED] = 0.0
    return False


@njit(cache=True)
def sense_row(b, state, walls, params, z, obs):
    """Range readings (draws ``z[3:9]``), the action mask and the nearest wall at robot ``b``'s pose; writes the
    sensor part of observation row ``obs[b]``."""
    px, py = state[b, X], state[b, Y]
    c, s = math.cos(state[b, HEADING]), math.sin(state[b, HEADING])
    state[b, HEADING_COS], state[b, HEADING_SIN] = c, s
    scale = params[P_RANGE_NOISE]
    for i in range(6):  # beams: slant range along the tilted beam = horizontal distance / cos(19.47°)
        dx, dy = c * _BEAM_COS[i] - s * _BEAM_SIN[i], s * _BEAM_COS[i] + c * _BEAM_SIN[i]
        h = ray_distance(px + _SENSOR_OFFSET * dx, py + _SENSOR_OFFSET * dy, dx, dy, walls)
        d = h / _COS_ELEVATION
        reading, too_close, no_return, normalised = measure_one(d, z[3 + i], scale)
        state[b, TRUE_RANGE + i], state[b, READING + i] = d, reading
        close, none = 1.0 if too_close else 0.0, 1.0 if no_return else 0.0
        state[b, TOO_CLOSE + i], state[b, NO_RETURN + i] = close, none
        obs[b, OBS_RANGE + i] = normalised
        obs[b, OBS_TOO_CLOSE + i] = close
        obs[b, OBS_NO_RETURN + i] = none
    obs[b, OBS_TIP_FAILED] = state[b, BLOCKED]
    radius = params[P_BODY_RADIUS]
    for j in range(3):  # the action mask: the mean landing keeps the body off the walls and the motion crosses none
        mx, my = params[P_MEAN_OFFSETS + 2 * j], params[P_MEAN_OFFSETS + 2 * j + 1]
        lx, ly = px + c * mx - s * my, py + s * mx + c * my
        clear = nearest_point(lx, ly, walls)[0] >= radius and not segment_crosses(px, py, lx, ly, walls)
        state[b, ALLOWED + j] = 1.0 if clear else 0.0
    d, fx, fy, k = nearest_point(px, py, walls)
    state[b, WALL_DISTANCE], state[b, FOOT_X], state[b, FOOT_Y], state[b, WALL_SEGMENT] = d, fx, fy, k


@njit(cache=True, error_model="numpy")
def advance_rows(actions, sim):
    """One step of every robot whose action is >= 0: tip, update its records, sense; writes the sensor part of
    its observation row. Each consumes one draw row of its block. ``sim``: the arrays of :data:`SIM_ARRAYS`.

    The same physics as ``tip_row`` and ``sense_row``, with the wall queries of the whole batch made by the
    batched geometry kernels (walls outside, queries inside). Queries the triangle inequality settles are
    skipped: a robot farther from every wall than a step plus the body radius can neither cross a wall nor land
    against one, so only robots near walls check their motions and landings.
    """
    near = _propose_tips(actions, sim)
    _check_motions(sim, near)
    _move_rows(actions, sim)
    _cast_beams(actions, sim)
    _mask_rows(actions, sim)
    _read_sensors(actions, sim)


@njit(cache=True, error_model="numpy")
def _propose_tips(actions, sim):
    """Step 1: the noisy landing and the checked mean landing of every robot that tips (blocked tips are counted
    here). Robots whose noisy motion could touch a wall or end within half the body radius of one are queued in
    ``groups[0]`` (their motions and end points in the scratch); returns how many."""
    state, params, normals, cursor = sim[A_STATE], sim[A_PARAMS], sim[A_NORMALS], sim[A_CURSOR]
    scratch, groups = sim[A_SCRATCH], sim[A_GROUPS]
    radius = params[P_BODY_RADIUS]
    near = 0
    for b in range(actions.shape[0]):
        scratch[TIP_ACTIVE, b] = 0.0
        a = actions[b]
        if a < 0:
            continue
        c_b = cursor[b]  # index the draws directly: a view per robot would cost two atomic reference counts
        state[b, STEPS] += 1.0
        if state[b, ALLOWED + a] < 0.5:
            state[b, BLOCKED] = 1.0
            state[b, BLOCKED_TIPS] += 1.0
            state[b, LAST_TIP_MOVED] = 0.0
            continue
        x, y = state[b, X], state[b, Y]
        hc, hs = state[b, HEADING_COS], state[b, HEADING_SIN]
        c, s = hc * _TIP_COS[a] - hs * _TIP_SIN[a], hs * _TIP_COS[a] + hc * _TIP_SIN[a]  # the tip's direction
        forward = params[P_FORWARD] + params[P_FORWARD_SD] * normals[b, c_b, 0]
        lateral = params[P_LATERAL] + params[P_LATERAL_SD] * normals[b, c_b, 1]  # +lateral: right of the tip
        dx, dy = forward * c + lateral * s, forward * s - lateral * c
        mx, my = params[P_MEAN_OFFSETS + 2 * a], params[P_MEAN_OFFSETS + 2 * a + 1]
        scratch[TIP_NX, b], scratch[TIP_NY, b] = x + dx, y + dy
        scratch[TIP_MX, b], scratch[TIP_MY, b] = x + hc * mx - hs * my, y + hs * mx + hc * my
        scratch[TIP_ACTIVE, b] = scratch[TIP_SAFE, b] = 1.0
        if state[b, WALL_DISTANCE] < math.sqrt(dx * dx + dy * dy) + 0.5 * radius + _MARGIN_CM:
            scratch[MV_AX, near], scratch[MV_AY, near] = x, y
            scratch[MV_BX, near] = scratch[C_X, near] = x + dx
            scratch[MV_BY, near] = scratch[C_Y, near] = y + dy
            groups[0, near] = b
            near += 1
    return near


@njit(cache=True, error_model="numpy")
def _check_motions(sim, near):
    """Step 2: do the ``near`` queued noisy motions touch a wall, or end too close to one? Those are not safe."""
    walls, params, scratch, groups = sim[A_WALLS], sim[A_PARAMS], sim[A_SCRATCH], sim[A_GROUPS]
    queries = (groups[0], 1, near)
    crossings(walls, queries, (scratch[MV_AX], scratch[MV_AY], scratch[MV_BX], scratch[MV_BY]), scratch[MV_HIT])
    nearest_squared(walls, queries, (scratch[C_X], scratch[C_Y]), scratch[C_D2], scratch[C_K])
    half_radius_sq = (0.5 * params[P_BODY_RADIUS]) ** 2
    for g in range(near):
        if scratch[MV_HIT, g] > 0.5 or scratch[C_D2, g] < half_radius_sq:
            scratch[TIP_SAFE, groups[0, g]] = 0.0


@njit(cache=True, error_model="numpy")
def _move_rows(actions, sim):
    """Step 3: move to the noisy landing, or the checked one where contact stops the body; dead reckoning;
    faces; oscillations."""
    state, params, normals, cursor, scratch = sim[A_STATE], sim[A_PARAMS], sim[A_NORMALS], sim[A_CURSOR], sim[A_SCRATCH]
    for b in range(actions.shape[0]):
        if scratch[TIP_ACTIVE, b] < 0.5:
            continue
        a = actions[b]
        if scratch[TIP_SAFE, b] > 0.5:
            state[b, X], state[b, Y] = scratch[TIP_NX, b], scratch[TIP_NY, b]
        else:
            state[b, X], state[b, Y] = scratch[TIP_MX, b], scratch[TIP_MY, b]
        turn = params[P_FRAME_TURN + a] + params[P_TURN_SD] * normals[b, cursor[b], 2]
        state[b, HEADING] = wrap_angle(state[b, HEADING] + turn)
        state[b, HEADING_COS], state[b, HEADING_SIN] = math.cos(state[b, HEADING]), math.sin(state[b, HEADING])
        dead_reckon(b, a, state, params)
        old, edge = int(state[b, FACE]), (int(state[b, EDGE0]) + a) % 3
        state[b, FACE] = _NEIGHBOR[old, edge]
        state[b, EDGE0] = _BACK_EDGE[old, edge]
        state[b, BLOCKED] = 0.0
        if a == 0 and state[b, LAST_TIP_MOVED] > 0.5:
            state[b, OSCILLATIONS] += 1.0  # undid the previous tip: the robot alternates between two faces
        state[b, LAST_TIP_MOVED] = 1.0


@njit(cache=True, error_model="numpy")
def _cast_beams(actions, sim):
    """Step 4: sensing geometry at the new poses, the six beams and the centre of every robot."""
    state, walls, scratch, groups = sim[A_STATE], sim[A_WALLS], sim[A_SCRATCH], sim[A_GROUPS]
    n = actions.shape[0]
    for b in range(n):
        px, py = state[b, X], state[b, Y]
        c, s = state[b, HEADING_COS], state[b, HEADING_SIN]
        for i in range(6):
            dx, dy = c * _BEAM_COS[i] - s * _BEAM_SIN[i], s * _BEAM_COS[i] + c * _BEAM_SIN[i]
            j = 6 * b + i
            scratch[R_OX, j], scratch[R_OY, j] = px + _SENSOR_OFFSET * dx, py + _SENSOR_OFFSET * dy
            scratch[R_DX, j], scratch[R_DY, j] = dx, dy
        scratch[PT_X, b], scratch[PT_Y, b] = px, py
    rays = (scratch[R_OX], scratch[R_OY], scratch[R_DX], scratch[R_DY])
    first_hits(walls, (groups[2], 6, 6 * n), rays, scratch[R_T])
    nearest_squared(walls, (groups[2], 1, n), (scratch[PT_X], scratch[PT_Y]), scratch[PT_D2], scratch[PT_K])


@njit(cache=True, error_model="numpy")
def _mask_rows(actions, sim):
    """Step 5: the action mask; robots near a wall check their three mean landings and motions."""
    state, walls, params, scratch, groups = sim[A_STATE], sim[A_WALLS], sim[A_PARAMS], sim[A_SCRATCH], sim[A_GROUPS]
    radius, reach = params[P_BODY_RADIUS], params[P_STEP_REACH]
    n = actions.shape[0]
    near = 0
    for b in range(n):
        if actions[b] < 0 or math.sqrt(scratch[PT_D2, b]) >= reach + radius + _MARGIN_CM:
            continue
        px, py = state[b, X], state[b, Y]
        c, s = state[b, HEADING_COS], state[b, HEADING_SIN]
        for j in range(3):
            mx, my = params[P_MEAN_OFFSETS + 2 * j], params[P_MEAN_OFFSETS + 2 * j + 1]
            q = 3 * near + j
            scratch[MV_AX, q], scratch[MV_AY, q] = px, py
            scratch[MV_BX, q] = scratch[C_X, q] = px + c * mx - s * my
            scratch[MV_BY, q] = scratch[C_Y, q] = py + s * mx + c * my
        groups[1, near] = b
        near += 1
    queries = (groups[1], 3, 3 * near)
    nearest_squared(walls, queries, (scratch[C_X], scratch[C_Y]), scratch[C_D2], scratch[C_K])
    crossings(walls, queries, (scratch[MV_AX], scratch[MV_AY], scratch[MV_BX], scratch[MV_BY]), scratch[MV_HIT])
    for b in range(n):
        if actions[b] >= 0:
            state[b, ALLOWED], state[b, ALLOWED + 1], state[b, ALLOWED + 2] = 1.0, 1.0, 1.0
    radius_sq = radius * radius
    for g in range(near):
        b = groups[1, g]
        for j in range(3):
            clear = scratch[C_D2, 3 * g + j] >= radius_sq and scratch[MV_HIT, 3 * g + j] < 0.5
            state[b, ALLOWED + j] = 1.0 if clear else 0.0


@njit(cache=True, error_model="numpy")
def _read_sensors(actions, sim):
    """Step 6: what the sensors report (the observation rows), the nearest wall, the ground-truth block."""
    state, walls, params, normals, cursor = sim[A_STATE], sim[A_WALLS], sim[A_PARAMS], sim[A_NORMALS], sim[A_CURSOR]
    obs, scratch = sim[A_OBS], sim[A_SCRATCH]
    scale = params[P_RANGE_NOISE]
    shared = walls.shape[0] == 1
    for b in range(actions.shape[0]):
        if actions[b] < 0:
            continue
        c_b = cursor[b]
        cursor[b] += 1
        for i in range(6):
            d = scratch[R_T, 6 * b + i] / _COS_ELEVATION  # slant range along the tilted beam
            reading, too_close, no_return, normalised = measure_one(d, normals[b, c_b, 3 + i], scale)
            close, none = 1.0 if too_close else 0.0, 1.0 if no_return else 0.0
            state[b, TRUE_RANGE + i], state[b, READING + i] = d, reading
            state[b, TOO_CLOSE + i], state[b, NO_RETURN + i] = close, none
            obs[b, OBS_RANGE + i] = normalised
            obs[b, OBS_TOO_CLOSE + i] = close
            obs[b, OBS_NO_RETURN + i] = none
        obs[b, OBS_TIP_FAILED] = state[b, BLOCKED]
        k, w = int(scratch[PT_K, b]), 0 if shared else b
        sx, sy, vx, vy = walls[w, k, 0], walls[w, k, 1], walls[w, k, 2], walls[w, k, 3]
        along = min(max(((state[b, X] - sx) * vx + (state[b, Y] - sy) * vy) * walls[w, k, 4], 0.0), 1.0)
        state[b, WALL_DISTANCE] = math.sqrt(scratch[PT_D2, b])
        state[b, FOOT_X], state[b, FOOT_Y] = sx + along * vx, sy + along * vy
        state[b, WALL_SEGMENT] = k
        write_info(b, state)


@njit(cache=True)
def write_info(b, state):
    """Row ``b``'s ground-truth block (``POSE_INFO`` to ``TIP_DIRECTIONS``) from its state."""
    heading = math.degrees(state[b, HEADING])
    state[b, POSE_INFO], state[b, POSE_INFO + 1], state[b, POSE_INFO + 2] = state[b, X], state[b, Y], heading
    state[b, DR_POSE_INFO], state[b, DR_POSE_INFO + 1] = state[b, DR_X], state[b, DR_Y]
    state[b, DR_POSE_INFO + 2] = math.degrees(state[b, DR_HEADING])
    state[b, TIP_DIRECTIONS] = heading  # in [0, 360): the others need at most one turn off
    state[b, TIP_DIRECTIONS + 1] = heading + 120.0 if heading < 240.0 else heading - 240.0
    state[b, TIP_DIRECTIONS + 2] = heading + 240.0 if heading < 120.0 else heading - 120.0


@njit(cache=True)
def plan_slot(b, sim):
    """Robot ``b``'s plan slot, the index of its walls (and of a task's per-plan tables): 0 where every robot
    shares one plan, else ``b``."""
    return 0 if sim[A_WALLS].shape[0] == 1 else b


@njit(cache=True)
def first_sense_row(b, sim):
    """First readings of freshly placed robot ``b`` (one draw row of its block); ``sim``: :data:`SIM_ARRAYS`."""
    state, walls, normals, cursor = sim[A_STATE], sim[A_WALLS], sim[A_NORMALS], sim[A_CURSOR]
    z = normals[b, cursor[b]]
    cursor[b] += 1
    sense_row(b, state, walls[plan_slot(b, sim)], sim[A_PARAMS], z, sim[A_OBS])
    write_info(b, state)


@njit(cache=True)
def write_base_metrics(b, state, out, first):
    """The metrics every task reports (:data:`BASE_METRICS`, in that order) into ``out[b]`` from column ``first``
    on: a task's first metrics (``BuckybotEnv.task_columns`` puts them there)."""
    for j in range(len(_BASE_METRIC_STATE)):
        out[b, first + j] = state[b, _BASE_METRIC_STATE[j]]


@njit(cache=True)
def _tip_rows(action, draws, state, walls, params):
    shared = walls.shape[0] == 1
    for b in range(action.shape[0]):
        if action[b] >= 0:
            tip_row(b, action[b], state, walls[0 if shared else b], params, draws[b])


@njit(cache=True)
def _sense_rows(rows, draws, state, walls, params, obs):
    shared = walls.shape[0] == 1
    for n in range(rows.shape[0]):
        b = rows[n]
        sense_row(b, state, walls[0 if shared else b], params, draws[n], obs)
