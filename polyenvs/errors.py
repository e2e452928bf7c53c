"""The caller's mistakes: :class:`InputError`, and the checks every layer raises it from.

Convention every command and family inherits from here: user input that cannot work raises ``InputError`` (a
``ValueError``) before any episode runs; the command line prints it as one line and exit status 2.
"""

from __future__ import annotations

from numbers import Integral

import numpy as np

__all__ = ["InputError", "check_count", "shown"]


class InputError(ValueError):
    """A bad argument from the caller (unknown id or policy, bad keyword arguments, seeds, counts).

    Distinct from a ``ValueError`` raised while an environment runs, which is a bug: the command line prints an
    ``InputError`` as one line and lets anything else show its traceback.
    """


def check_count(name: str, value, minimum: int, maximum: int | None = None) -> int:
    """An integer (not a bool, float or string) in ``[minimum, maximum]``; raises :class:`InputError`.

    For values given in Python; the command line's flags go through :func:`int_flag`."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Integral):
        raise InputError(f"{name} must be an integer, got {value!r}")
    value = int(value)  # a numpy integer as a Python one (exact: it is Integral)
    if value < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise InputError(f"{name} must be <= {maximum}, got {value}")
    return value


def shown(text) -> str:
    """``text`` for an error message, its middle cut out when it is long (a 5000-digit number stays one line)."""
    text = str(text).strip()
    return text if len(text) <= 40 else f"{text[:12]}...{text[-12:]} ({len(text)} characters)"
