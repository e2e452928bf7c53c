"""Fail fast, with the fix, when the test dependencies are not installed (instead of one traceback per module)."""

from __future__ import annotations

import importlib.util

import pytest

_REQUIRED = ("gymnasium", "numpy", "numba")


def pytest_configure(config):
    missing = [name for name in _REQUIRED if importlib.util.find_spec(name) is None]
    if missing:
        raise pytest.UsageError(
            f"missing {', '.join(missing)}: install the project first, e.g. "
            'python3 -m venv .venv && .venv/bin/pip install ".[dev,train,distributed]" && .venv/bin/python -m pytest'
        )
