"""Constructor-argument checks that raise ``ValueError`` naming the parameter (never ``assert``)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["check_action", "check_finite", "check_in_range", "check_positive", "check_choice"]


def check_finite(name: str, value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


def check_positive(name: str, value, *, allow_zero: bool = False) -> float:
    value = check_finite(name, value)
    if value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {bound}, got {value!r}")
    return value


def check_in_range(name: str, value, low: float, high: float) -> float:
    value = check_finite(name, value)
    if not low <= value <= high:
        raise ValueError(f"{name} must be in [{low}, {high}], got {value!r}")
    return value


def check_choice(name: str, value, choices) -> str:
    if value not in choices:
        raise ValueError(f"{name} must be one of {sorted(choices)}, got {value!r}")
    return value


def check_action(action_space, action):
    """Reject actions outside the action space (and NaN) with a clear message instead of moving the robot."""
    if isinstance(action, np.ndarray) and action.dtype.kind == "f" and np.isnan(action).any():
        raise ValueError(f"action contains NaN: {action!r}")
    if not action_space.contains(action):
        raise ValueError(f"action {action!r} is outside the action space {action_space}")
    return action
