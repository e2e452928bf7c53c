"""The beasts' sensors as one compiled call per step: encoders with backlash, tilt switches, foot contacts.

Paper section 2: joint encoders whose resolution (under 0.0008 degrees) is far finer than the gears' backlash, and
twelve 1-bit tilt sensors that together give the coarse orientation with respect to gravity. *Ours*: the backlash
is a dead band (the encoder sits on the motor side of the worm drive: the motor shaft follows the joint only once
the joint has taken up the play), the tilt switches lie along the twelve vertex directions of an icosahedron and
read 1 when their axis points more than a threshold below the horizontal, and each foot has a binary contact switch
(MuJoCo's contact sensor of the foot sphere against the floor).

The inputs are MuJoCo's own arrays (``qpos``, ``qvel``, ``sensordata``: the model's sensors are evaluated inside
``mj_step``, at the start of its last substep, 2 ms before the state in ``qpos``) and the environment's packed state;
the kernel writes the observation in place and reports divergence, so a step costs one ``mj_step`` and one call here.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = ["N_TILT", "TILT_AXES", "VELOCITY_CLIP", "DIVERGED_SPEED", "sense", "actuate"]

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

# Layout of the packed float parameters ``consts``.
HALF_BAND, INV_DT, TILT_SIN, PRIVILEGED, TORQUE_NORM = 0, 1, 2, 3, 4
# Layout of ``track``: the body's (x, y) at the previous tick and at the start, and the heading's unit vector.
PREV_X, PREV_Y, START_X, START_Y, HEAD_X, HEAD_Y = 0, 1, 2, 3, 4, 5
# Layout of the per-step summary ``scalars`` the tasks read.
VELOCITY, DISTANCE, FEET_MASK, N_FEET, OTHER_CONTACTS, TORQUE_SQ, SPIN_SQ = 0, 1, 2, 3, 4, 5, 6
N_SCALARS = 7


@njit(cache=True)
def actuate(action, low, span, frozen, hold, ctrl, applied):
    """Check an action (finite, in [-1, 1]) and write the actuator controls; nothing is written if it fails.

    ``ctrl = low + (a + 1) / 2 * span`` per joint, except frozen joints, which get ``hold``. Returns 0 if the action
    was accepted, else 1 + the index of the first bad entry.
    """
    n = action.shape[0]
    for j in range(n):
        a = action[j]
        if not (-1.0 <= a <= 1.0):  # also false for NaN
            return j + 1
    for j in range(n):
        a = action[j]
        applied[j] = a
        ctrl[j] = hold[j] if frozen[j] else low[j] + 0.5 * (a + 1.0) * span[j]
    return 0


@njit(cache=True)
def sense(qpos, qvel, sensordata, force, warnings, motor, reading, applied, tilt_axes, consts, track, obs, scalars):
    """Write the observation into ``obs`` (float32) and the tasks' summary into ``scalars``; True if diverged.

    ``motor`` (n_joints) is each encoder's motor-side angle, dragged along by the joint across the backlash band;
    ``reading`` holds the previous readings (for the velocity estimate) and is overwritten with the new ones.
    ``scalars``: body velocity along the heading over the tick and distance along it from the start (``track``,
    whose previous position is updated), the feet-on-floor bitmask (bit i = limb i + 1) and count, contacts of
    anything but a foot with the floor, mean squared torque / limit^2, squared body spin (rad^2/s^2).
    On divergence nothing is written, so the previous observation stays the last finite one. MuJoCo resets a state
    it finds non-finite (to the model's reference pose) and counts a warning: ``warnings`` (MjData's warning counts,
    cleared by ``mj_resetData``) catches that silent reset.
    """
    for w in UNSTABLE_WARNINGS:
        if warnings[w] > 0:
            return True
    nj = motor.shape[0]
    for i in range(qpos.shape[0]):
        if not math.isfinite(qpos[i]):
            return True
    for i in range(qvel.shape[0]):
        v = qvel[i]
        if not (abs(v) < DIVERGED_SPEED):
            return True
    half = consts[HALF_BAND]
    inv_dt = consts[INV_DT]
    n_limbs = sensordata.shape[0] - 4
    k = 0
    for j in range(nj):
        q = qpos[7 + j]
        m = min(max(motor[j], q - half), q + half)
        motor[j] = m
        v = (m - reading[j]) * inv_dt
        reading[j] = m
        obs[k + j] = m
        obs[k + nj + j] = min(max(v, -VELOCITY_CLIP), VELOCITY_CLIP)
    k += 2 * nj
    # The world's up direction in the body frame: a switch is on when its axis points down by more than the
    # threshold, i.e. its component along "up" is below -sin(threshold).
    ux, uy, uz = sensordata[n_limbs + 1], sensordata[n_limbs + 2], sensordata[n_limbs + 3]
    for t in range(tilt_axes.shape[0]):
        dot = tilt_axes[t, 0] * ux + tilt_axes[t, 1] * uy + tilt_axes[t, 2] * uz
        obs[k + t] = 1.0 if dot < -consts[TILT_SIN] else 0.0
    k += tilt_axes.shape[0]
    mask = 0.0
    n_feet = 0.0
    found = 0.0
    for i in range(n_limbs):
        on = sensordata[i] > 0.5
        obs[k + i] = 1.0 if on else 0.0
        found += sensordata[i]
        if on:
            mask += 2.0**i
            n_feet += 1.0
    k += n_limbs
    for j in range(nj):
        obs[k + j] = applied[j]
    k += nj
    if consts[PRIVILEGED] > 0.5:
        for i in range(7):
            obs[k + i] = qpos[i]
        for i in range(6):
            obs[k + 7 + i] = min(max(qvel[i], -VELOCITY_CLIP), VELOCITY_CLIP)
    hx, hy = track[HEAD_X], track[HEAD_Y]
    scalars[VELOCITY] = ((qpos[0] - track[PREV_X]) * hx + (qpos[1] - track[PREV_Y]) * hy) * inv_dt
    scalars[DISTANCE] = (qpos[0] - track[START_X]) * hx + (qpos[1] - track[START_Y]) * hy
    track[PREV_X] = qpos[0]
    track[PREV_Y] = qpos[1]
    scalars[FEET_MASK] = mask
    scalars[N_FEET] = n_feet
    scalars[OTHER_CONTACTS] = sensordata[n_limbs] - found
    sq = 0.0
    for j in range(force.shape[0]):
        sq += force[j] * force[j]
    scalars[TORQUE_SQ] = sq * consts[TORQUE_NORM]
    scalars[SPIN_SQ] = qvel[3] * qvel[3] + qvel[4] * qvel[4] + qvel[5] * qvel[5]
    return False
