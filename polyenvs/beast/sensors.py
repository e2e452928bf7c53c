"""The beasts' sensors and servos as one compiled call each per step: encoders with backlash, tilt switches, foot
switches with a debounce, position servos with a dead band.

Paper section 2: joint encoders whose resolution (under 0.0008 degrees) is far finer than the gears' backlash, and
twelve 1-bit tilt sensors that together give the coarse orientation with respect to gravity. *Ours*: the backlash
is a dead band (the encoder sits on the motor side of the worm drive: the motor shaft follows the joint only once
the joint has taken up the play), the tilt switches lie along the twelve vertex directions of an icosahedron and
read 1 when their axis points more than a threshold below the horizontal, and each foot has a binary contact switch
(MuJoCo's contact sensor of the foot sphere against the floor), which firmware debounces: a change is reported only
once the new reading has held for ``switch_debounce_ms`` (a mechanical switch bounces for milliseconds, and a foot
resting lightly on a soft contact flickers). The tasks judge MuJoCo's contacts themselves; the debounced switches
are what the robot, and so the policy, sees. Each position servo has a dead band: it drives its joint only while the
joint is further than ``servo_deadband_deg`` from the target and stops at the band's edge, where the worm drive,
which does not backdrive, holds it; so the target MuJoCo's servo tracks follows the command through a play of
+- the dead band (a command that wanders inside it moves nothing).

The inputs are MuJoCo's own arrays (``qpos``, ``qvel``, ``sensordata``: the model's sensors are evaluated inside
``mj_step``, at the start of its last substep, 2 ms before the state in ``qpos``) and the environment's packed state;
the kernel writes the observation in place and reports divergence, so a step costs one ``mj_step`` and one call here.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from polyenvs.core.jit import njit

__all__ = [
    "N_TILT",
    "TILT_AXES",
    "VELOCITY_CLIP",
    "DIVERGED_SPEED",
    "StepSummary",
    "actuate",
    "observation_layout",
    "observation_layout_of",
    "sense",
]

_PHI = (1 + math.sqrt(5)) / 2
#: The tilt switches' axes in the body frame: the icosahedron's 12 vertex directions (*ours*, spec beast.md).
TILT_AXES = np.array(
    [(0, s1, s2 * _PHI) for s1 in (1, -1) for s2 in (1, -1)]
    + [(s1, s2 * _PHI, 0) for s1 in (1, -1) for s2 in (1, -1)]
    + [(s2 * _PHI, 0, s1) for s1 in (1, -1) for s2 in (1, -1)],
    dtype=np.float64,
) / math.sqrt(1 + _PHI**2)
N_TILT = len(TILT_AXES)
#: Encoder and body velocities are clipped to this (rad/s, m/s) in the observation: the space stays bounded.
VELOCITY_CLIP = 50.0
#: A joint or body speed above this (rad/s, m/s), or anything non-finite in the state, is a diverged simulation.
DIVERGED_SPEED = 1.0e3
#: MuJoCo's warnings for a non-finite or huge position, velocity or acceleration (mjtWarning values).
UNSTABLE_WARNINGS = (3, 4, 5)

#: The privileged tail of an observation: torso position, orientation (w, x, y, z), linear and angular velocity.
PRIVILEGED_PARTS = (("body_pos", 3), ("body_quat", 4), ("body_linvel", 3), ("body_angvel", 3))


def observation_layout(n_limbs: int, privileged: bool = False, command: int = 0) -> dict[str, slice]:
    """Name -> slice of a beast observation: the sensors (written by :func:`sense`), the privileged tail when asked
    for, then a task's constant ``command`` (e.g. the turn the sharp turn is to make), when it has one."""
    nj = 3 * n_limbs
    parts = [("joint_pos", nj), ("joint_vel", nj), ("tilt", N_TILT), ("foot_contact", n_limbs), ("prev_action", nj)]
    parts += list(PRIVILEGED_PARTS) if privileged else []
    parts += [("command", command)] if command else []
    layout, start = {}, 0
    for name, size in parts:
        layout[name] = slice(start, start + size)
        start += size
    return layout


@functools.cache
def observation_layout_of(obs_dim: int) -> dict[str, slice]:
    """The layout of a beast observation of this length (10 n + 12 sensors, + 13 privileged, + 2 command: the sizes
    of the 4-, 6- and 8-beast never coincide). Cached: treat the dict as read-only."""
    for n_limbs in (4, 6, 8):
        for privileged in (False, True):
            for command in (0, 2):
                layout = observation_layout(n_limbs, privileged, command)
                if max(part.stop for part in layout.values()) == obs_dim:
                    return layout
    raise ValueError(f"observation length {obs_dim} is not a beast's (10 n + 12, + 13 privileged, + 2 command)")


# Rows of the per-joint state ``joints`` (n_rows, n_joints): the action scaling (control = LOW + (a + 1)/2 SPAN),
# the control held by frozen joints and whether a joint is frozen, the last applied action, the encoders' motor-side
# angles and their previous readings, the joint's limits (the encoder range) and the servo's dead band (rad, 0: none).
# Then two rows per foot switch, in the first n_limbs columns: the state it reports (-1: take the next reading, as at
# reset) and for how many ticks the raw reading has differed from it. Packed so that a kernel call unboxes one array,
# not twelve.
LOW, SPAN, HOLD, FROZEN, APPLIED, MOTOR, READING, LIMIT_LOW, LIMIT_HIGH, DEADBAND, SWITCH, SWITCH_HELD = range(12)
N_JOINT_ROWS = 12
# Layout of ``misc``: parameters (the debounce in ticks: a change is reported once the raw reading has held that
# many ticks; 1 or less reports every reading), then the body's (x, y) at the previous tick and at the start and the
# heading's unit vector, then the per-step summary the tasks read.
HALF_BAND, INV_DT, TILT_SIN, PRIVILEGED, TORQUE_NORM, DEBOUNCE_TICKS = range(6)
PREV_X, PREV_Y, START_X, START_Y, HEAD_X, HEAD_Y = range(6, 12)
VELOCITY, DISTANCE, FEET_MASK, N_FEET, OTHER_CONTACTS, TORQUE_SQ, SPIN_SQ, POWER = range(12, 20)
N_MISC = 20
SUMMARY = slice(VELOCITY, N_MISC)


class StepSummary(NamedTuple):
    """The summary of one tick that a task scores (``misc[SUMMARY]``, in its columns' order; see :func:`sense`):
    velocity (m/s) along the heading and distance (m) along it from the start, the feet-on-floor bitmask (bit i =
    limb i + 1) and count, contacts of anything but a foot with the floor, mean squared torque / limit^2, squared
    body spin (rad^2/s^2), the actuators' mechanical power (W, see :func:`sense`). Python floats, as the kernel wrote
    them."""

    velocity: float
    distance: float
    feet_mask: float
    n_feet: float
    other_contacts: float
    torque_sq: float
    spin_sq: float
    power: float


@njit(cache=True)
def actuate(action, joints, ctrl):
    """Check an action (finite, in [-1, 1]) and write the actuator controls; nothing is written if it fails.

    The command is ``LOW + (a + 1) / 2 * SPAN`` per joint, except frozen joints, which get ``HOLD``. A joint with a
    dead band keeps its servo's target (``ctrl``) while the command stays within the band of it, and otherwise moves
    it to the band's near edge (a play: the servo stops driving at the edge, and the worm drive holds the joint).
    Returns 0 if the action was accepted, else 1 + the index of the first bad entry.
    """
    n = action.shape[0]
    for j in range(n):
        a = action[j]
        if not (-1.0 <= a <= 1.0):  # also false for NaN
            return j + 1
    for j in range(n):
        a = float(action[j])
        joints[APPLIED, j] = a
        command = joints[HOLD, j] if joints[FROZEN, j] > 0.5 else joints[LOW, j] + 0.5 * (a + 1.0) * joints[SPAN, j]
        band = joints[DEADBAND, j]
        ctrl[j] = command if band <= 0.0 else min(max(ctrl[j], command - band), command + band)
    return 0


@njit(cache=True)
def sense(data, tilt_axes, joints, misc, obs):
    """Write the observation into ``obs`` (float32) and the tasks' summary into ``misc``; True if diverged.
    ``data``: MjData's views ``(qpos, qvel, sensordata, actuator_force, warning counts)``.

    ``joints[MOTOR]`` is each encoder's motor-side angle, dragged along by the joint across the backlash band;
    ``joints[READING]`` holds the previous readings (for the velocity estimate) and is overwritten with the new ones.
    The angle reported is clipped to the joint's limits: MuJoCo's soft limits let a loaded joint sink a little past
    them, which the real hard stop does not, and the observation space's bounds are the limits.
    The summary (``misc[SUMMARY]``): body velocity along the heading over the tick and distance along it from the
    start (the previous position is updated), the feet-on-floor bitmask (bit i = limb i + 1) and count, contacts of
    anything but a foot with the floor, mean squared torque / limit^2, squared body spin (rad^2/s^2), and the
    actuators' mechanical power P = sum over joints of max(0, tau_j qdot_j) (W: the model is SI, kg, m, s, so
    torques are N m and joint speeds rad/s). tau_j is ``actuator_force[j]``, the torque actuator j's servo or motor
    applied over the tick's last physics substep (clamped to its force range; actuator j drives joint j with gear
    1, so it is the torque at the joint), and qdot_j the joint's speed at the tick's end, ``qvel[6 + j]`` after the
    free joint's 6 dofs. Only the positive part counts: negative work (lowering the body, braking a limb) is not
    recovered, since a worm drive does not backdrive. The summary's feet are MuJoCo's contacts; the observation's
    are the debounced switches (``joints[SWITCH]``).
    On divergence nothing is written, so the previous observation stays the last finite one. MuJoCo resets a state
    it finds non-finite (to the model's reference pose) and counts a warning: ``warnings`` (MjData's warning counts,
    cleared by ``mj_resetData``) catches that silent reset.
    """
    qpos, qvel, sensordata, force, warnings = data
    if _diverged(qpos, qvel, warnings):
        return True
    nj = joints.shape[1]
    n_limbs = sensordata.shape[0] - 4
    _read_encoders(qpos, joints, misc, obs)
    k = 2 * nj
    _read_tilts(sensordata[n_limbs + 1 : n_limbs + 4], tilt_axes, misc[TILT_SIN], obs[k : k + tilt_axes.shape[0]])
    k += tilt_axes.shape[0]
    _read_switches(sensordata, joints, misc, obs[k : k + n_limbs])
    k += n_limbs
    for j in range(nj):
        obs[k + j] = joints[APPLIED, j]
    k += nj
    if misc[PRIVILEGED] > 0.5:
        for i in range(7):
            obs[k + i] = qpos[i]
        for i in range(6):
            obs[k + 7 + i] = min(max(qvel[i], -VELOCITY_CLIP), VELOCITY_CLIP)
    _summarise_body(qpos, qvel, force, misc)
    return False


@njit(cache=True)
def _diverged(qpos, qvel, warnings) -> bool:
    """Whether MuJoCo warned of instability, or a position is non-finite, or a speed is beyond belief."""
    for w in UNSTABLE_WARNINGS:
        if warnings[w] > 0:
            return True
    for i in range(qpos.shape[0]):
        if not math.isfinite(qpos[i]):
            return True
    for i in range(qvel.shape[0]):
        if not (abs(qvel[i]) < DIVERGED_SPEED):
            return True
    return False


@njit(cache=True)
def _read_encoders(qpos, joints, misc, obs):
    """Each encoder's angle (motor side, across the backlash band, clipped to the joint's limits) into
    ``obs[:nj]`` and its velocity estimate into ``obs[nj:2 nj]``."""
    nj = joints.shape[1]
    half, inv_dt = misc[HALF_BAND], misc[INV_DT]
    for j in range(nj):
        q = qpos[7 + j]
        m = min(max(joints[MOTOR, j], q - half), q + half)
        joints[MOTOR, j] = m
        v = (m - joints[READING, j]) * inv_dt
        joints[READING, j] = m
        obs[j] = min(max(m, joints[LIMIT_LOW, j]), joints[LIMIT_HIGH, j])
        obs[nj + j] = min(max(v, -VELOCITY_CLIP), VELOCITY_CLIP)


@njit(cache=True)
def _read_tilts(up, tilt_axes, tilt_sin, out):
    """The tilt switches: ``up`` is the world's up direction in the body frame; a switch is on when its axis
    points down by more than the threshold, i.e. its component along "up" is below ``-tilt_sin``."""
    for t in range(tilt_axes.shape[0]):
        dot = tilt_axes[t, 0] * up[0] + tilt_axes[t, 1] * up[1] + tilt_axes[t, 2] * up[2]
        out[t] = 1.0 if dot < -tilt_sin else 0.0


@njit(cache=True)
def _read_switches(sensordata, joints, misc, out):
    """The foot switches, debounced (a change is reported once the new reading has held ``misc[DEBOUNCE_TICKS]``
    readings), into ``out``; MuJoCo's own contacts (the feet bitmask, their count, other contacts) into the
    summary."""
    n_limbs = out.shape[0]
    mask = 0.0
    n_feet = 0.0
    found = 0.0
    debounce = misc[DEBOUNCE_TICKS]
    for i in range(n_limbs):
        on = sensordata[i] > 0.5
        raw = 1.0 if on else 0.0
        if joints[SWITCH, i] < 0.0 or debounce <= 1.0 or raw == joints[SWITCH, i]:
            joints[SWITCH, i], joints[SWITCH_HELD, i] = raw, 0.0
        else:
            joints[SWITCH_HELD, i] += 1.0
            if joints[SWITCH_HELD, i] >= debounce:
                joints[SWITCH, i], joints[SWITCH_HELD, i] = raw, 0.0
        out[i] = joints[SWITCH, i]
        found += sensordata[i]
        if on:
            mask += 2.0**i
            n_feet += 1.0
    misc[FEET_MASK] = mask
    misc[N_FEET] = n_feet
    misc[OTHER_CONTACTS] = sensordata[n_limbs] - found


@njit(cache=True)
def _summarise_body(qpos, qvel, force, misc):
    """The body's part of the summary: velocity and distance along the heading, squared torque, squared spin, the
    actuators' mechanical power (``force[j]`` drives the dof ``6 + j``)."""
    inv_dt = misc[INV_DT]
    hx, hy = misc[HEAD_X], misc[HEAD_Y]
    misc[VELOCITY] = ((qpos[0] - misc[PREV_X]) * hx + (qpos[1] - misc[PREV_Y]) * hy) * inv_dt
    misc[DISTANCE] = (qpos[0] - misc[START_X]) * hx + (qpos[1] - misc[START_Y]) * hy
    misc[PREV_X] = qpos[0]
    misc[PREV_Y] = qpos[1]
    sq = 0.0
    power = 0.0
    for j in range(force.shape[0]):
        sq += force[j] * force[j]
        power += max(0.0, force[j] * qvel[6 + j])
    misc[TORQUE_SQ] = sq * misc[TORQUE_NORM]
    misc[SPIN_SQ] = qvel[3] * qvel[3] + qvel[4] * qvel[4] + qvel[5] * qvel[5]
    misc[POWER] = power
