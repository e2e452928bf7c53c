"""A beast step in one compiled call: the servos, the physics ticks, the sensors and the task's rules, for a batch.

:func:`step_rows` steps every active row of a batch of environments: it checks the row's action and writes the
servos' controls (:func:`polyenvs.beast.sensors.actuate`), then for each 10 ms tick of the control period runs
MuJoCo's ``mj_step`` ``frame_skip`` times (:data:`polyenvs.beast.mujoco_extra.mj_step_at`, the C function itself),
reads the sensors (:func:`polyenvs.beast.sensors.sense`) and applies the task's rules (the tumble counter, the reward
terms, termination, the metrics and the actuators' power), exactly as the tasks' definitions in
:mod:`polyenvs.beast.tasks` describe them. ``gym.make`` runs it over a batch of one; the native vector env
(:mod:`polyenvs.beast.vector`) over slices of its batch, one thread per slice: the kernel is compiled ``nogil``, so
the threads step their MuJoCo models at the same time.

Each row's MuJoCo arrays are reached through their addresses (``handles``: MjModel, MjData and the MjData arrays the
sensors read), which stay valid as long as the environment that owns the MjData lives; everything else is packed in
arrays with the batch axis first (:class:`Rows`), a row per environment, which the environment's own arrays view.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import carray, njit, types
from numba.extending import intrinsic

from polyenvs.beast import sensors as S
from polyenvs.beast.model import CONTROL_DT
from polyenvs.beast.mujoco_extra import mj_step_at

__all__ = ["Rows", "allocate_rows", "count_tumble", "step_rows"]

#: Ticks a support (set of feet on the floor) must hold to count as a stance: 0.2 s, as in the working tumble.
STANCE_TICKS = 20
#: A tumble turns the body by more than this since the last one (rad; the 4-beast turns 109.5 deg, the 6-beast 70.5).
TUMBLE_TURN_RAD = math.radians(45)
#: The spin (rad^2/s^2) below which a recovered stance counts as still (0.1 rad/s).
STILL_SPIN_SQ = 0.01
_DEGREES = 180.0 / math.pi  # what math.degrees multiplies by

# Columns of ``handles``: the addresses of MjModel, MjData and the MjData arrays a step reads and writes.
MODEL, DATA, QPOS, QVEL, CTRL, SENSORDATA, FORCE, WARNINGS = range(8)
N_HANDLES = 8
# MuJoCo's warning statistics are (lastinfo, number) int32 pairs: ``number`` of warning w is int32 2 w of the array
# that starts at ``number[0]``; there are 8 warnings (mjNWARNING).
_N_WARNINGS = 8

# Which task's rules a row applies, and which reward (the -v1 ids replace some terms, see polyenvs.beast.tasks).
TUMBLE, ROLL, TURN, RECOVER = 1, 2, 3, 4
OWN_REWARD, SUCCESS_AND_TIME, HEADING_GAIN = 0, 1, 2

# Columns of ``task``: the row's constants, where each of its metrics is (-1: the task has none of that name), then
# its running state: ticks into the episode, diverged, the ticks a still stance has held (recover), the power summed
# (W), the stances of the last tumbles (turn: x, y of up to three) and the tumble counter's state (COUNTER...).
(KIND, REWARD, FRAME_SKIP, TICKS, CTRL_WEIGHT, SUCCESS_REWARD, TIME_COST, HEADING_REWARD, TURN_DEG, TARGET_MASK,
 WEIGHT_N) = range(11)  # fmt: skip
(M_SUCCESS, M_TIME, M_TIME_TO_STANCE, M_DISTANCE, M_TUMBLES, M_SPEED, M_HEADING_CHANGE, M_HEADING_ERROR,
 M_MEAN_POWER, M_PEAK_POWER, M_COST) = range(11, 22)  # fmt: skip
ELAPSED, UNSTABLE, STILL_HELD, POWER_SUM, N_STANCES = range(22, 27)
STANCES = 27  # 6 columns
COUNTER = 33
# The tumble counter's columns (from COUNTER): the current support's feet bitmask, the candidate support (-1: none),
# the ticks it has held, whether a new support has yet to turn enough, the tumbles counted, the body's quaternion at
# the last tumble.
SUPPORT, CANDIDATE, HELD, PENDING, COUNT, QUAT = range(6)
N_COUNTER = 10
N_TASK = COUNTER + N_COUNTER
#: The metric columns by metric name (the task's ``metric_names`` say which exist and in what order).
METRIC_COLUMNS = {
    "success": M_SUCCESS,
    "time_s": M_TIME,
    "time_to_stance_s": M_TIME_TO_STANCE,
    "distance_m": M_DISTANCE,
    "tumbles": M_TUMBLES,
    "speed_m_s": M_SPEED,
    "heading_change_deg": M_HEADING_CHANGE,
    "heading_error_deg": M_HEADING_ERROR,
    "mean_power_w": M_MEAN_POWER,
    "peak_power_w": M_PEAK_POWER,
    "cost_of_transport": M_COST,
}
#: The task constants by the task attribute that holds them.
TASK_CONSTANTS = {
    "success_reward": SUCCESS_REWARD,
    "time_cost": TIME_COST,
    "heading_reward": HEADING_REWARD,
    "turn_deg": TURN_DEG,
}

# Columns of ``out``: up to three reward terms (the task's ``reward_names`` order), their sum, terminated, diverged.
TERMS, REWARD_SUM, TERMINATED, DIVERGED = 0, 3, 4, 5
N_OUT = 6


class Rows(NamedTuple):
    """A batch's packed arrays, batch axis first: the MuJoCo addresses, the joints' and the summary's state
    (:mod:`polyenvs.beast.sensors`), the task's constants and state, the metrics (the task's ``metric_names``
    order), the observations and the step's outputs."""

    handles: np.ndarray
    joints: np.ndarray
    misc: np.ndarray
    task: np.ndarray
    metrics: np.ndarray
    obs: np.ndarray
    out: np.ndarray

    def row(self, e: int) -> Rows:
        """Row ``e`` as a batch of one (views)."""
        return Rows(*(array[e : e + 1] for array in self))


def allocate_rows(n: int, n_joints: int, obs_size: int, n_metrics: int) -> Rows:
    """Zeroed rows for ``n`` environments."""
    return Rows(
        np.zeros((n, N_HANDLES), dtype=np.int64),
        np.zeros((n, S.N_JOINT_ROWS, n_joints)),
        np.zeros((n, S.N_MISC)),
        np.zeros((n, N_TASK)),
        np.zeros((n, n_metrics)),
        np.zeros((n, obs_size), dtype=np.float32),
        np.zeros((n, N_OUT)),
    )


def _pointer_at(element):
    """An intrinsic that reads an address (an integer) as a pointer to ``element`` values."""

    def pointer_at(typingctx, address):
        signature = types.CPointer(element)(types.intp)

        def codegen(context, builder, sig, args):
            return builder.inttoptr(args[0], context.get_value_type(sig.return_type))

        return signature, codegen

    return intrinsic(pointer_at)


_float64_at = _pointer_at(types.float64)
_int32_at = _pointer_at(types.int32)


@njit(cache=True, nogil=True)
def step_rows(active, actions, handles, joints, misc, task, metrics, obs, out):  # noqa: PLR0913, PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Step every row with ``active[e]`` under ``actions[e]``; 0, or 1 + the index of the first bad entry of the
    first row whose action is not in [-1, 1] (that row and those after it are left as they were)."""
    for e in range(active.shape[0]):
        if active[e]:
            bad = _step_row(actions[e], handles[e], joints[e], misc[e], task[e], metrics[e], obs[e], out[e])
            if bad:
                return bad
    return 0


@njit(cache=True, nogil=True)
def _step_row(action, handles, joints, misc, task, metrics, obs, out):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """One environment's step (see the module docstring); the arguments are its rows."""
    nj = joints.shape[1]
    n_limbs = nj // 3
    qpos = carray(_float64_at(handles[QPOS]), 7 + nj)
    qvel = carray(_float64_at(handles[QVEL]), 6 + nj)
    ctrl = carray(_float64_at(handles[CTRL]), nj)
    sensordata = carray(_float64_at(handles[SENSORDATA]), n_limbs + 4)
    force = carray(_float64_at(handles[FORCE]), nj)
    warnings = carray(_int32_at(handles[WARNINGS]), 2 * _N_WARNINGS)[::2]
    bad = S.actuate(action, joints, ctrl)
    if bad:
        return bad
    # The controls are written once: the action is held through the control period's ticks.
    out[TERMINATED] = 0.0
    out[DIVERGED] = 0.0
    data = (qpos, qvel, sensordata, force, warnings)
    for tick in range(int(task[TICKS])):
        for _ in range(int(task[FRAME_SKIP])):
            mj_step_at(handles[MODEL], handles[DATA])
        task[ELAPSED] += 1.0
        if task[UNSTABLE] > 0.5 or S.sense(data, S.TILT_AXES, joints, misc, obs):
            # A diverged simulation: a zero reward for the whole step, however many ticks went well before.
            task[UNSTABLE] = 1.0
            out[DIVERGED] = 1.0
            out[TERMS] = out[TERMS + 1] = out[TERMS + 2] = out[REWARD_SUM] = 0.0
            return 0
        terminated = _task_tick(qpos, misc, task, metrics, out, tick == 0)
        _record_power(misc[S.POWER], task, metrics)
        if terminated:
            out[TERMINATED] = 1.0
            break
    n_terms = 2 if task[KIND] == ROLL or task[KIND] == TURN else 3
    reward = 0.0
    for k in range(n_terms):
        reward += out[TERMS + k]
    out[REWARD_SUM] = reward
    return 0


@njit(cache=True)
def _add_terms(out, first, a, b, c):
    """A tick's reward terms into ``out``: the first tick's as they are, later ticks' added."""
    if first:
        out[TERMS], out[TERMS + 1], out[TERMS + 2] = a, b, c
    else:
        out[TERMS] += a
        out[TERMS + 1] += b
        out[TERMS + 2] += c


@njit(cache=True)
def _task_tick(qpos, misc, task, metrics, out, first) -> bool:
    """The task's rules for one tick, from the sensors' summary in ``misc``: the reward terms into ``out``, the
    metrics; True when the episode terminates."""
    kind = task[KIND]
    ctrl = -task[CTRL_WEIGHT] * misc[S.TORQUE_SQ]
    if kind == RECOVER:
        return _recover_tick(misc, task, metrics, out, first, ctrl)
    counted = count_tumble(
        task[COUNTER : COUNTER + N_COUNTER], misc[S.FEET_MASK], misc[S.N_FEET], misc[S.OTHER_CONTACTS], qpos
    )
    if kind == TUMBLE:
        return _tumble_tick(misc, task, metrics, out, first, ctrl, counted)
    if kind == TURN:
        before = metrics[int(task[M_HEADING_ERROR])]
        _turn_tick(qpos, misc, task, metrics, counted)
        if task[REWARD] == HEADING_GAIN:
            gain = task[HEADING_REWARD] * (before - metrics[int(task[M_HEADING_ERROR])]) / 180.0
            _add_terms(out, first, gain, ctrl, 0.0)
            return False
    else:  # ROLL
        metrics[int(task[M_DISTANCE])] = misc[S.DISTANCE]
        metrics[int(task[M_TUMBLES])] = task[COUNTER + COUNT]
        metrics[int(task[M_SPEED])] = misc[S.DISTANCE] / (task[ELAPSED] * CONTROL_DT)
    _add_terms(out, first, misc[S.VELOCITY], ctrl, 0.0)
    return False


@njit(cache=True)
def _tumble_tick(misc, task, metrics, out, first, ctrl, counted) -> bool:  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    success = counted and (task[TARGET_MASK] < 0.0 or misc[S.FEET_MASK] == task[TARGET_MASK])
    metrics[int(task[M_DISTANCE])] = misc[S.DISTANCE]
    metrics[int(task[M_TIME])] = task[ELAPSED] * CONTROL_DT
    if success:
        metrics[int(task[M_SUCCESS])] = 1.0
    bonus = task[SUCCESS_REWARD] if success else 0.0
    if task[REWARD] == SUCCESS_AND_TIME:
        _add_terms(out, first, bonus, -task[TIME_COST] * CONTROL_DT, ctrl)
    else:
        _add_terms(out, first, misc[S.VELOCITY], bonus, ctrl)
    return success


@njit(cache=True)
def _turn_tick(qpos, misc, task, metrics, counted) -> None:
    """The heading of travel over the last two tumbles, measured between the stances they ended in."""
    if counted:
        n = int(task[N_STANCES])
        if n == 3:  # keep the last two, then the new one
            for k in range(4):
                task[STANCES + k] = task[STANCES + 2 + k]
            n = 2
        task[STANCES + 2 * n] = qpos[0]
        task[STANCES + 2 * n + 1] = qpos[1]
        task[N_STANCES] = n + 1
        if n + 1 == 3:
            dx = task[STANCES + 4] - task[STANCES]
            dy = task[STANCES + 5] - task[STANCES + 1]
            change = math.atan2(dy, dx) * _DEGREES
            metrics[int(task[M_HEADING_CHANGE])] = change
            metrics[int(task[M_HEADING_ERROR])] = abs((change - task[TURN_DEG] + 180.0) % 360.0 - 180.0)
        metrics[int(task[M_TUMBLES])] = task[COUNTER + COUNT]
    metrics[int(task[M_DISTANCE])] = misc[S.DISTANCE]


@njit(cache=True)
def _recover_tick(misc, task, metrics, out, first, ctrl) -> bool:
    """A still stance: three or more feet down, nothing else touching, spinning slower than 0.1 rad/s, held."""
    other = misc[S.OTHER_CONTACTS] > 0
    still = misc[S.N_FEET] >= 3 and not other and misc[S.SPIN_SQ] < STILL_SPIN_SQ
    task[STILL_HELD] = task[STILL_HELD] + 1.0 if still else 0.0
    success = task[STILL_HELD] >= STANCE_TICKS
    metrics[int(task[M_TIME_TO_STANCE])] = (task[ELAPSED] - (task[STILL_HELD] if success else 0.0)) * CONTROL_DT
    if success:
        metrics[int(task[M_SUCCESS])] = 1.0
    bonus = task[SUCCESS_REWARD] if success else 0.0
    if task[REWARD] == SUCCESS_AND_TIME:
        _add_terms(out, first, bonus, -task[TIME_COST] * CONTROL_DT, ctrl)
    else:
        _add_terms(out, first, 0.01 * (misc[S.N_FEET] - (3.0 if other else 0.0)), bonus, ctrl)
    return success


@njit(cache=True)
def _record_power(power, task, metrics) -> None:
    """A tick's mechanical power (W) into the power metrics, after the task's rules have written its distance."""
    mean = int(task[M_MEAN_POWER])
    if mean < 0:
        return
    task[POWER_SUM] += power
    metrics[mean] = task[POWER_SUM] / task[ELAPSED]
    peak = int(task[M_PEAK_POWER])
    if power > metrics[peak]:
        metrics[peak] = power
    cost = int(task[M_COST])
    if cost >= 0:
        distance = metrics[int(task[M_DISTANCE])]
        energy_j = task[POWER_SUM] * CONTROL_DT
        metrics[cost] = energy_j / (task[WEIGHT_N] * distance) if distance > 0.0 else 0.0


@njit(cache=True)
def count_tumble(counter, mask, n_feet, other_contacts, qpos) -> bool:
    """Feed one tick to a tumble counter (``counter``: its :data:`N_COUNTER` columns) from the feet bitmask and
    count, the contacts of anything but a foot with the floor and MuJoCo's qpos; True when a tumble has just
    completed (:class:`polyenvs.beast.env.TumbleCounter` says what counts)."""
    if not (n_feet >= 3 and other_contacts == 0):
        counter[CANDIDATE], counter[HELD] = -1.0, 0.0
        return False
    if mask != counter[CANDIDATE]:
        counter[CANDIDATE], counter[HELD] = mask, 0.0
        return False
    counter[HELD] += 1.0
    if counter[HELD] == STANCE_TICKS and mask != counter[SUPPORT]:
        # The first support of an episode (the feet are not yet down when it starts) is where it stands.
        counter[PENDING] = 1.0 if counter[SUPPORT] != 0.0 else 0.0
        counter[SUPPORT] = mask
    if counter[PENDING] < 0.5 or mask != counter[SUPPORT] or counter[HELD] < STANCE_TICKS:
        return False
    dot = 0.0
    for i in range(4):
        dot += counter[QUAT + i] * qpos[3 + i]
    if 2.0 * math.acos(min(1.0, abs(dot))) <= TUMBLE_TURN_RAD:
        return False
    counter[PENDING] = 0.0
    for i in range(4):
        counter[QUAT + i] = qpos[3 + i]
    counter[COUNT] += 1.0
    return True
