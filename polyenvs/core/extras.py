"""The optional extras (``pyproject.toml``'s ``[project.optional-dependencies]``), as a message names them."""

from __future__ import annotations

__all__ = ["install_hint"]


def install_hint(*extras: str) -> str:
    """How to install optional extras, for a message: polyenvs is not on PyPI, so from a clone (the README says how
    from a wheel). ``install_hint("mujoco")`` -> ``pip install ".[mujoco]" in a polyenvs clone``."""
    return f'pip install ".[{",".join(extras)}]" in a polyenvs clone'
