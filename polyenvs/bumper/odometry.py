"""Odometry of the two-wheeled bumper cart from its left and right wheel travels (the paper's Part 2).

Derivation (Dye, "Mapping with only a bumper", Part 2; equations missing from the text, rederived here). During one
logged stage both motors run at constant (unequal) speeds, so the cart turns about a fixed centre at a constant
rate. Let ``a`` and ``b`` be the left and right wheel travels and ``d`` the wheel base. Both wheels turn through the
same angle ``θ`` about the centre, the left wheel on radius ``r - d/2`` and the right on ``r + d/2``, where ``r`` is
the signed radius of the axle centre's path (positive: centre to the left)::

    a = (r - d/2) θ,   b = (r + d/2) θ   =>   θ = (b - a) / d,   r = (d/2) (a + b) / (b - a).

In the start frame (x ahead, y to the left) the axle centre moves on that circle to ``(r sin θ, r (1 - cos θ))``.
The form has a singularity at ``a = b`` (a straight line, ``r`` infinite). Writing ``s = r θ = (a + b)/2`` for the
arc length of the axle centre's path, the displacement is a chord of length ``L = 2 r sin(θ/2) = s sin(θ/2)/(θ/2)``
at angle ``θ/2`` to the start heading::

    Δx = L cos(θ/2),   Δy = L sin(θ/2),   Δheading = θ,

which is regular everywhere: ``a = b`` gives a straight line of length ``a``, and ``a = -b`` a spin in place by
``2b/d`` (``s = 0``, so ``L = 0``). It holds for negative ``a`` or ``b`` (backing up, turning). In the world frame,
from heading ``φ``: ``x += L cos(φ + θ/2)``, ``y += L sin(φ + θ/2)``, ``φ += θ``.

The paper's robot logs the encoder ticks of both wheels for each stage of a cycle (drive, back up, turn), so the
imperfect turn in place is accounted for; one tick is 0.0675 in of wheel travel (12:1 gearing on the RCX rotation
sensor). The result is only as good as ``d``: a wheel-base error of 5% turns a 90° spin into a 4.3° heading error
(``δθ/θ = -δd/d``).
"""

from __future__ import annotations

import math

import numpy as np

from polyenvs.core.jit import njit

__all__ = ["TICK_CM", "chord_factor", "dead_reckon", "odometry_step"]

#: Wheel travel per encoder tick: 0.0675 in (the paper, Part 1) = 0.171450 cm.
TICK_CM = 0.0675 * 2.54


@njit(cache=True)
def chord_factor(theta):
    """``sin(θ/2) / (θ/2)``: the chord of an arc over its length (1 at θ = 0, series below 1e-4)."""
    half = 0.5 * theta
    if abs(half) < 1e-4:
        return 1.0 - half * half / 6.0
    return math.sin(half) / half


@njit(cache=True)
def odometry_step(x, y, heading, a, b, wheel_base):
    """Pose after wheel travels ``a`` (left) and ``b`` (right), cm, from ``(x, y, heading)`` (cm, cm, rad).

    The singularity-free form of the module docstring; returns ``(x, y, heading)``.
    """
    theta = (b - a) / wheel_base
    chord = 0.5 * (a + b) * chord_factor(theta)
    mid = heading + 0.5 * theta
    return x + chord * math.cos(mid), y + chord * math.sin(mid), heading + theta


def dead_reckon(start_pose, ticks, wheel_base_cm: float, tick_cm: float = TICK_CM) -> np.ndarray:
    """The paper's Part 2: every stage's odometry added end to end from ``start_pose``.

    Args:
        start_pose: ``(x_cm, y_cm, heading_rad)``.
        ticks: ``(n, 2)`` left and right ticks of consecutive stages.

    Returns:
        ``(n + 1, 3)`` poses, the start first.
    """
    ticks = np.asarray(ticks, dtype=np.float64).reshape(-1, 2)
    poses = np.empty((len(ticks) + 1, 3))
    poses[0] = start_pose
    x, y, h = (float(v) for v in start_pose)
    for i, (left, right) in enumerate(ticks):
        x, y, h = odometry_step(x, y, h, left * tick_cm, right * tick_cm, wheel_base_cm)
        poses[i + 1] = x, y, h
    return poses
