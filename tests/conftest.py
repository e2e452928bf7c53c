"""Fail fast, with the fix, when the test dependencies are not installed (instead of one traceback per module)."""

from __future__ import annotations

import importlib.util
import os

import pytest

# MuJoCo renders headless through EGL here (osmesa also works where its library is installed); without a setting it
# would look for a display. The rendering tests skip, with the reason, where no GL works at all.
os.environ.setdefault("MUJOCO_GL", "egl")

_REQUIRED = ("gymnasium", "numpy", "numba")


def pytest_configure(config):
    missing = [name for name in _REQUIRED if importlib.util.find_spec(name) is None]
    if missing:
        raise pytest.UsageError(
            f"missing {', '.join(missing)}: install the project first, e.g. "
            'python3 -m venv .venv && .venv/bin/pip install ".[dev,train,distributed,mujoco]" && .venv/bin/python -m pytest'
        )
