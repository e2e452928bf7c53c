"""The LV-MaxSonar-EZ range finders and the paper's wall identification.

Buckybot paper, "Test Results" and "Simulation and Results": a reading is the true range plus noise
``(0.013 d + 0.448) w`` cm (eq. 6, w standard normal), rounded to the nearest 2.54 cm by the sensor's own
filtering. Readings below 30.48 cm do not settle ("too close": the robot is near an obstacle); readings above
182.88 cm are ignored ("no return").
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.buckybot.geometry import HEXAGON_INRADIUS_CM, SENSOR_AZIMUTHS_RAD, SENSOR_ELEVATION_RAD
from polyenvs.core import libm
from polyenvs.core.jit import njit

__all__ = [
    "RANGE_MAX_CM",
    "RANGE_MIN_CM",
    "RANGE_QUANTUM_CM",
    "SENSOR_PAIR_SEPARATION_RAD",
    "horizontal_range",
    "measure_ranges",
    "measure_into",
    "measure_one",
    "measure_ranges_normalised",
    "wall_from_pair",
    "walls_from_readings",
]

#: Closer than this (12 in) the sensor does not settle (paper, "Test Results").
RANGE_MIN_CM = 30.48
#: Farther than this (72 in) readings are ignored (paper, "Test Results").
RANGE_MAX_CM = 182.88
#: The sensor reports to the nearest inch.
RANGE_QUANTUM_CM = 2.54
#: Eq. 6 noise fit: sd = 0.013 d + 0.448 cm.
NOISE_SLOPE = 0.013
NOISE_OFFSET_CM = 0.448

_COS_ELEVATION = float(libm.cos(SENSOR_ELEVATION_RAD))
_PER_QUANTUM = 1.0 / RANGE_QUANTUM_CM
_INCHES_AT_MAX = float(round(RANGE_MAX_CM / RANGE_QUANTUM_CM))  # 72: a reading of n inches observes as n / 72
#: Azimuth separation from sensor i to sensor i+1 (cyclic): alternately 75.52° and 44.48°.
SENSOR_PAIR_SEPARATION_RAD = np.diff(np.append(SENSOR_AZIMUTHS_RAD, SENSOR_AZIMUTHS_RAD[0] + 2 * np.pi))


def measure_ranges(
    true_range: np.ndarray, normals: np.ndarray, noise_scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Turn true slant ranges into what the sensor reports.

    Args:
        true_range: slant ranges in cm (``inf`` where the beam hits nothing).
        normals: standard normal draws of the same shape.
        noise_scale: multiplies eq. 6's standard deviation (0 = noiseless, still quantised).

    Returns:
        ``(reading, too_close, no_return)``: the quantised reading in cm (``nan`` where invalid) and the two
        boolean invalid cases.
    """
    reading, too_close, no_return, _ = measure_ranges_normalised(true_range, normals, noise_scale)
    return reading, too_close, no_return


def measure_ranges_normalised(true_range: np.ndarray, normals: np.ndarray, noise_scale: float = 1.0):
    """:func:`measure_ranges`, plus the observation's normalised range: reading / 182.88 cm, 0 when too close,
    1 when there is no return."""
    true_range = np.asarray(true_range, dtype=np.float64)
    flat_range = np.ascontiguousarray(true_range).reshape(-1)
    flat_normals = np.ascontiguousarray(np.broadcast_to(normals, true_range.shape), dtype=np.float64).reshape(-1)
    reading = np.empty(flat_range.shape)
    too_close = np.empty(flat_range.shape, dtype=np.bool_)
    no_return = np.empty(flat_range.shape, dtype=np.bool_)
    normalised = np.empty(flat_range.shape, dtype=np.float32)
    measure_into(flat_range, flat_normals, float(noise_scale), reading, too_close, no_return, normalised)
    shape = true_range.shape
    return reading.reshape(shape), too_close.reshape(shape), no_return.reshape(shape), normalised.reshape(shape)


@njit(cache=True)
def measure_one(d, normal, noise_scale):
    """One reading from the true slant range ``d`` (cm) and a standard normal draw.

    Returns ``(reading, too_close, no_return, normalised)``: the quantised reading (nan where invalid), the two
    invalid cases, and the observation's value (reading / 182.88 cm, 0 when too close, 1 when no return).
    """
    noisy = d + (NOISE_SLOPE * d + NOISE_OFFSET_CM) * (noise_scale * normal)
    inches = np.floor(noisy * _PER_QUANTUM + 0.5)  # the sensor reports whole inches (nan, inf stay so)
    r = inches * RANGE_QUANTUM_CM
    too_close = r < RANGE_MIN_CM - 1e-9
    no_return = not (r <= RANGE_MAX_CM + 1e-9)  # also true for inf and nan
    if too_close:
        return math.nan, True, False, 0.0
    if no_return:
        return math.nan, False, True, 1.0
    return r, False, False, inches / _INCHES_AT_MAX


@njit(cache=True)
def measure_into(true_range, normals, noise_scale, reading, too_close, no_return, normalised):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Compiled core of :func:`measure_ranges_normalised` on 1-D arrays, writing into the output arrays."""
    for i in range(true_range.shape[0]):
        reading[i], too_close[i], no_return[i], normalised[i] = measure_one(true_range[i], normals[i], noise_scale)


def horizontal_range(reading: np.ndarray) -> np.ndarray:
    """Horizontal distance from the robot's centre to a beam's hit point: (reading + 11.95 cm) cos 19.47°.

    The paper's wall geometry works on horizontal distances; using raw slant ranges is 6-10% off.
    """
    return (reading + HEXAGON_INRADIUS_CM) * _COS_ELEVATION


def wall_from_pair(x: np.ndarray, y: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A wall's distance and normal direction from two adjacent beams (paper, eqs. 1-3, corrected eq. 4).

    Args:
        x: horizontal range along the first beam (cm).
        y: horizontal range along the second beam, at azimuth ``phi`` counter-clockwise from the first.
        phi: azimuth separation of the two beams (rad).

    Returns:
        ``(d, delta)``: the wall's perpendicular distance from the robot's centre (Heron: d = 2A/z) and the
        azimuth of its normal relative to the beams' bisector, positive towards the second beam.
    """
    z = np.sqrt(x * x + y * y - 2.0 * x * y * libm.cos(phi))  # law of cosines
    s = 0.5 * (x + y + z)
    area = np.sqrt(np.maximum(s * (s - x) * (s - y) * (s - z), 0.0))  # Heron
    d = 2.0 * area / z
    delta = libm.arctan2((x - y) * libm.cos(0.5 * phi), (x + y) * libm.sin(0.5 * phi))
    return d, delta


def walls_from_readings(reading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Walls seen by the six cyclically adjacent sensor pairs.

    Args:
        reading: ``(..., 6)`` readings in cm, ``nan`` where invalid. A wall needs both sensors of a pair.

    Returns:
        ``(distance, normal_azimuth)``: ``(..., 6)`` arrays, pair i = sensors (i, i+1 mod 6); ``nan`` where the pair
        does not see a wall. Azimuths are in the resting face's frame (radians).
    """
    h = horizontal_range(reading)
    x, y = h, np.roll(h, -1, axis=-1)
    d, delta = wall_from_pair(x, y, SENSOR_PAIR_SEPARATION_RAD)
    bisector = SENSOR_AZIMUTHS_RAD + 0.5 * SENSOR_PAIR_SEPARATION_RAD
    return d, bisector + delta
