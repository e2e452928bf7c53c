"""What a robot's own sensors report: the GP2D12 infrared range finders, the goal light and trilateration.

GP2D12 (paper, Section 5.0.1): the Maxelbot's A/D value converts to inches with the paper's
``ConvertSensorReadingToInches``, ``inches = (6787 / (raw - 3) - 4) / 2.54``; its inverse is
``raw = 3 + 6787 / (cm + 4)``. The sensor sees about 10 to 80 cm (raw 487.8 to 83.8); nearer objects read as 10 cm,
farther ones leave a low random floor (raw 0 to 25, *ours*), which AP-lite's ``reading > 30`` filter removes. The
X80Pro reports the same sensor as 0..80 with 80 meaning nothing seen: here the paper's conversion of the raw value
to centimetres, clipped to [0, 80]. Noise (*ours*, the feasibility study): 3% of the distance plus raw sd 2.

All functions are numpy, vectorised over any shape.
"""

from __future__ import annotations

import numpy as np

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
    "raw_from_observation",
    "x80pro_from_raw",
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


def ir_readings(distance_cm, normals, uniforms, noise_fraction=0.03, raw_sd=2.0):
    """Raw Maxelbot readings for true beam distances (``inf`` or anything beyond 80 cm: nothing seen).

    Args:
        distance_cm: true distances along the beams, any shape ``S``.
        normals: standard normals, shape ``S + (2,)`` (distance noise, raw noise).
        uniforms: uniforms in [0, 1), shape ``S`` (the noise floor).
        noise_fraction: sd of the distance noise as a fraction of the distance.
        raw_sd: sd of the additive noise on the raw value.

    Returns:
        raw values in [0, 550], float64.
    """
    d = np.asarray(distance_cm, dtype=np.float64)
    seen = d < IR_MAX_CM
    noisy = np.maximum(np.where(seen, d, IR_MAX_CM) * (1.0 + noise_fraction * normals[..., 0]), IR_MIN_CM)
    raw = raw_from_cm(noisy) + raw_sd * normals[..., 1]
    raw = np.where(seen, raw, IR_FLOOR_RAW_MAX * uniforms)
    return np.clip(raw, 0.0, MAXELBOT_RAW_MAX)


def x80pro_from_raw(raw):
    """The X80Pro's 0..80 scale (80 = nothing seen) for raw values: centimetres by the paper's conversion."""
    raw = np.asarray(raw, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        cm = np.where(raw > 3.0 + 6787.0 / (X80PRO_NOTHING + 4.0), cm_from_raw(raw), X80PRO_NOTHING)
    return np.clip(cm, 0.0, X80PRO_NOTHING)


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
