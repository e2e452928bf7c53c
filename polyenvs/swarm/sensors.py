"""What a robot's own sensors report: the GP2D12 infrared range finders, the goal light and trilateration.

GP2D12 (paper, Section 5.0.1): the Maxelbot's A/D value converts to inches with the paper's
``ConvertSensorReadingToInches``, ``inches = (6787 / (raw - 3) - 4) / 2.54``; its inverse is
``raw = 3 + 6787 / (cm + 4)``. The sensor sees about 10 to 80 cm (raw 487.8 to 83.8); nearer objects read as 10 cm,
farther ones leave a low random floor (raw 0 to 25, *ours*), which AP-lite's ``reading > 30`` filter removes. The
X80Pro reports the same sensor as 0..80 with 80 meaning nothing seen: here the paper's conversion of the raw value
to centimetres, clipped to [0, 80]. Noise (*ours*, the feasibility study): 3% of the distance plus raw sd 2.

The scalar models (:func:`raw_reading`, :func:`x80pro_reading`) are compiled and shared by the environments'
observation kernel and the numpy-facing functions, so the model exists once.
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = [
    "IR_FLOOR_RAW_MAX",
    "IR_MAX_CM",
    "IR_MIN_CM",
    "MAXELBOT_RAW_MAX",
    "X80PRO_NOTHING",
    "cm_from_raw",
    "inches_from_raw",
    "ir_readings",
    "raw_from_cm",
    "observation_from_raw",
    "raw_reading",
    "raw_from_observation",
    "x80pro_from_raw",
    "wrap_angle",
    "write_observations",
    "x80pro_reading",
]

#: GP2D12 rated range (Sharp data sheet; the paper's "about 10 to 80 cm").
IR_MIN_CM = 10.0
IR_MAX_CM = 80.0
#: Largest raw Maxelbot A/D value (paper: "between 0 and approximately 550").
MAXELBOT_RAW_MAX = 550.0
#: Beyond its range the A/D reads a random floor in [0, IR_FLOOR_RAW_MAX] (*ours*; below AP-lite's filter of 30).
IR_FLOOR_RAW_MAX = 25.0
#: The X80Pro's "nothing seen" reading (paper, Section 3).
X80PRO_NOTHING = 80.0


def inches_from_raw(raw):
    """The paper's ``ConvertSensorReadingToInches`` (singular at raw 3; only meaningful for raw > 3)."""
    return (6787.0 / (np.asarray(raw, dtype=np.float64) - 3.0) - 4.0) / 2.54


def cm_from_raw(raw):
    """The paper's conversion in centimetres."""
    return 6787.0 / (np.asarray(raw, dtype=np.float64) - 3.0) - 4.0


def raw_from_cm(cm):
    """The inverse of the paper's conversion: the noiseless raw value of an object ``cm`` away."""
    return 3.0 + 6787.0 / (np.asarray(cm, dtype=np.float64) + 4.0)


@njit(cache=True, inline="always")
def raw_reading(distance_cm, distance_normal, raw_normal, uniform, noise_fraction, raw_sd):
    """One raw Maxelbot reading of an object ``distance_cm`` away (``inf`` or beyond 80 cm: nothing seen): the
    distance with ``noise_fraction`` relative noise, clamped at 10 cm, converted by the paper's function, plus
    ``raw_sd`` of raw noise, in [0, 550]; the noise floor ``25 * uniform`` when nothing is seen."""
    if distance_cm < IR_MAX_CM:
        noisy = max(distance_cm * (1.0 + noise_fraction * distance_normal), IR_MIN_CM)
        raw = 3.0 + 6787.0 / (noisy + 4.0) + raw_sd * raw_normal
    else:
        raw = IR_FLOOR_RAW_MAX * uniform
    return min(max(raw, 0.0), MAXELBOT_RAW_MAX)


@njit(cache=True, inline="always")
def x80pro_reading(raw):
    """The X80Pro's 0..80 scale (80 = nothing seen) for a raw value: centimetres by the paper's conversion."""
    if raw > 3.0 + 6787.0 / (X80PRO_NOTHING + 4.0):
        return min(max(6787.0 / (raw - 3.0) - 4.0, 0.0), X80PRO_NOTHING)
    return X80PRO_NOTHING


@njit(cache=True)
def _readings(distance_cm, normals, uniforms, noise_fraction, raw_sd, out):
    for i in range(distance_cm.shape[0]):
        out[i] = raw_reading(distance_cm[i], normals[i, 0], normals[i, 1], uniforms[i], noise_fraction, raw_sd)


@njit(cache=True)
def _x80pro(raw, out):
    for i in range(raw.shape[0]):
        out[i] = x80pro_reading(raw[i])


def ir_readings(distance_cm, normals, uniforms, noise_fraction=0.03, raw_sd=2.0):
    """Raw Maxelbot readings (:func:`raw_reading`) for true beam distances of any shape ``S``; ``normals`` has
    shape ``S + (2,)`` (distance noise, raw noise), ``uniforms`` shape ``S`` (the noise floor)."""
    d = np.asarray(distance_cm, dtype=np.float64)
    out = np.empty(d.size)
    _readings(d.reshape(-1), np.asarray(normals, dtype=np.float64).reshape(-1, 2),
              np.asarray(uniforms, dtype=np.float64).reshape(-1), float(noise_fraction), float(raw_sd), out)  # fmt: skip
    return out.reshape(d.shape)


def x80pro_from_raw(raw):
    """The X80Pro's 0..80 scale for raw values (:func:`x80pro_reading`), any shape."""
    r = np.asarray(raw, dtype=np.float64)
    out = np.empty(r.size)
    _x80pro(r.reshape(-1), out)
    return out.reshape(r.shape)


def observation_from_raw(raw, ir_scale: str):
    """The IR part of an observation in [0, 1]: raw / 550 (Maxelbot) or reading / 80 (X80Pro, 1 = nothing)."""
    if ir_scale == "maxelbot":
        return np.asarray(raw, dtype=np.float64) / MAXELBOT_RAW_MAX
    return x80pro_from_raw(raw) / X80PRO_NOTHING


def raw_from_observation(observation, ir_scale: str):
    """Maxelbot-equivalent raw values from the IR part of an observation (what AP-lite's pseudocode expects).

    An X80Pro reading of 80 (nothing seen) becomes raw 0, which AP-lite's ``reading > 30`` filter drops.
    """
    obs = np.asarray(observation, dtype=np.float64)
    if ir_scale == "maxelbot":
        return obs * MAXELBOT_RAW_MAX
    cm = obs * X80PRO_NOTHING
    return np.where(cm < X80PRO_NOTHING, raw_from_cm(cm), 0.0)


@njit(cache=True, inline="always")
def wrap_angle(angle):
    """``angle`` (rad) wrapped into [-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


@njit(cache=True)
def write_observations(robots, todo, sensed, goals, per, draws, params, out):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """The family's part of every robot's observation row in ``todo``, written into ``out`` ``(N, D)`` float32
    (rows of inactive robots are 0; rows not in ``todo`` are left as they are).

    Layout (``env.observation_structure``): IR 0-3, light 4-5, neighbours 6.. (range / comm, bearing / pi, mask
    per slot), and the last powers in the last two columns; the columns between (a task's own parts) are zeroed
    here and written by the task.

    Args:
        robots: ``(pose, active, powers)``: poses, who is in the episode, and the last commanded powers.
        todo: ``(N,)`` uint8: the rows to write.
        sensed: ``(beams, nb_index, nb_range)``: ``(N, 4)`` true beam distances (m, ``inf`` for nothing within
            reach) and the ``(N, k)`` trilateration neighbours from :func:`polyenvs.swarm.core.sense`.
        goals: ``(E, 2)`` each environment's light; ``per``: robots per environment (row i is in environment
            ``i // per``).
        draws: ``(normals, floor)``: ``(N, 9 + 2k + ...)`` standard normals: IR (distance, raw) x 4, light
            bearing, k ranges, k bearings (then the task's, unread here); ``(N, 4)`` uniforms for the IR noise
            floor.
        params: ``[ir_noise, ir_raw_sd, light_noise_rad, range_noise_m, bearing_noise_rad, comm_range_m,
            x80pro (0/1), light_reference_m]``.
    """
    pose, active, powers = robots
    beams, nb_index, nb_range = sensed
    normals, floor = draws
    n, width = out.shape
    k = nb_index.shape[1]
    ir_noise, raw_sd, light_noise, range_noise = params[0], params[1], params[2], params[3]
    bearing_noise, comm, x80, reference = params[4], params[5], params[6] > 0.5, params[7]
    for i in range(n):
        if not todo[i]:
            continue
        for c in range(width):
            out[i, c] = 0.0
        if not active[i]:
            continue
        x, y, h = pose[i, 0], pose[i, 1], pose[i, 2]
        for s in range(4):
            raw = raw_reading(100.0 * beams[i, s], normals[i, 2 * s], normals[i, 2 * s + 1], floor[i, s], ir_noise,
                              raw_sd)  # fmt: skip
            out[i, s] = x80pro_reading(raw) / X80PRO_NOTHING if x80 else raw / MAXELBOT_RAW_MAX
        e = i // per
        gx, gy = goals[e, 0] - x, goals[e, 1] - y
        out[i, 4] = wrap_angle(math.atan2(gy, gx) - h + light_noise * normals[i, 8]) / math.pi
        d = math.hypot(gx, gy) / reference
        out[i, 5] = 1.0 / (1.0 + d * d)
        for q in range(k):
            j = nb_index[i, q]
            if j < 0:
                break
            measured = min(max(nb_range[i, q] + range_noise * normals[i, 9 + q], 0.0), comm)
            bearing = math.atan2(pose[j, 1] - y, pose[j, 0] - x) - h + bearing_noise * normals[i, 9 + k + q]
            out[i, 6 + 3 * q] = measured / comm
            out[i, 7 + 3 * q] = wrap_angle(bearing) / math.pi
            out[i, 8 + 3 * q] = 1.0
        out[i, width - 2] = powers[i, 0]
        out[i, width - 1] = powers[i, 1]
