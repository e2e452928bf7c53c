"""Argument checks that raise ``ValueError`` naming the parameter (never ``assert``: it vanishes under ``-O``).

Conventions every environment and baseline inherits from here:

- Every physical parameter has a documented plausible range, checked at construction with ``check_in_range``;
  the range is what keeps rewards and observations finite and the geometry honest, so it is part of the API.
- A number is a real number: ``bool`` and ``str`` are refused even though ``float(True)`` and ``float("50")``
  work, and so are NaN and infinities.
- Messages show values as the user wrote them (``10.0``, not ``np.float64(10.0)``).
- A call that raises changes nothing: validate everything first, then mutate.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "check_action",
    "check_bool",
    "check_choice",
    "check_finite",
    "check_in_range",
    "check_int",
    "check_options",
    "check_positive",
    "real_array",
    "show",
]


def show(value) -> str:
    """``value`` for an error message: numpy scalars as plain numbers, everything else as ``repr``."""
    if isinstance(value, np.generic):
        value = value.item()
    return repr(value)


def check_finite(name: str, value) -> float:
    """A finite real number (``bool`` and ``str`` are not numbers here)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a number, got {show(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


def check_positive(name: str, value, *, allow_zero: bool = False) -> float:
    value = check_finite(name, value)
    if value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {bound}, got {value!r}")
    return value


def check_in_range(name: str, value, low: float, high: float, *, low_open: bool = False) -> float:
    """A finite number in ``[low, high]`` (``(low, high]`` with ``low_open``)."""
    value = check_finite(name, value)
    if not (low < value if low_open else low <= value) or not value <= high:
        raise ValueError(f"{name} must be in {'(' if low_open else '['}{low:g}, {high:g}], got {value!r}")
    return value


def check_bool(name: str, value) -> bool:
    """A switch: ``True`` or ``False`` (not 0/1, and not the string "false", which ``bool`` calls true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be true or false, got {show(value)}")
    return bool(value)


def check_int(name: str, value, low: int, high: int | None = None) -> int:
    """An integer (not a bool, not a float) in ``[low, high]``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer, got {show(value)}")
    value = int(value)
    if value < low or (high is not None and value > high):
        bound = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise ValueError(f"{name} must be {bound}, got {value}")
    return value


def check_choice(name: str, value, choices) -> str:
    """One of ``choices`` (a string there; a value of any other type, hashable or not, is refused by name)."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {sorted(choices)}, got {show(value)}")
    return value


def check_options(options, allowed) -> dict:
    """Reset options: ``None`` or a dict whose keys are all in ``allowed`` (the names, in the order to list them)."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise ValueError(f"options must be a dict or None, got {show(options)}")
    unknown = sorted(set(options) - set(allowed), key=repr)
    if unknown:
        expected = f"expected some of {list(allowed)}" if allowed else "this environment takes none"
        raise ValueError(f"unknown reset option(s) {unknown}; {expected}")
    return options


def real_array(name: str, value, dtype=np.float64) -> np.ndarray:
    """``value`` as an array of real numbers: complex, bool, string and object input is refused, not cast (numpy
    would drop an imaginary part with only a warning, and turn ``True`` into 1)."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be real numbers, got {show(value)}") from None
    if array.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be real numbers, got {show(value)}")
    return array.astype(dtype, copy=False)


def check_action(action_space, action):
    """Reject actions outside the action space (and NaN, and anything not real numbers: a bool, a complex number)
    with a clear message instead of moving the robot."""
    if np.isnan(real_array("action", action)).any():
        raise ValueError(f"action contains NaN: {action!r}")
    if not action_space.contains(action):
        raise ValueError(f"action {show(action)} is outside the action space {action_space}")
    return action
