"""The estimators scored on each environment's logs (``polyenvs localize``), in one table keyed by its id: name ->
``"module:Class"``, the paper's first. A new environment's estimators go here; the registry row describes the
environment only."""

from __future__ import annotations

__all__ = ["ESTIMATORS"]

#: The localizers of the cart's exploration logs: the paper's bump-space filter first, then dead reckoning.
_CART = {
    "mcl": "polyenvs.estimators.bumper:BumpSpaceMCL",
    "dead_reckoning": "polyenvs.estimators.bumper:DeadReckoning",
}

#: Environment id -> its estimators, in the registry's order.
ESTIMATORS: dict[str, dict[str, str]] = {
    "polyenvs/BumperCartExplore-v0": _CART,
    "polyenvs/BumperCartExplore-v2": _CART,
}
