"""Estimators: localizers that read an environment's logs, the third kind of thing polyenvs holds (beside Gymnasium
ids and PettingZoo modules), scored on logged rollouts by the localization benchmark
(:mod:`polyenvs.evaluation.localization`). The bumper cart's are in :mod:`polyenvs.estimators.bumper`.

An estimator is any object with two methods (:class:`Estimator`):

- ``reset(context, start_pose, rng)``: a new run in a known map. ``context`` is what the environment says a
  localizer may know (for the bumper cart, :class:`polyenvs.bumper.env.LocalizationContext`: the map and the
  cart's nominal geometry); ``start_pose`` is the true start ``(x_cm, y_cm, heading_rad)``, which a global
  localizer ignores and dead reckoning needs; ``rng`` is the run's own ``numpy.random.Generator`` (every random
  number must come from it, so runs repeat bit for bit).
- ``update(log) -> pose``: one cycle's log (the environment's observation, e.g. tick counts and the bump bit);
  returns the estimate ``(x_cm, y_cm, heading_rad)`` of the pose at the end of the cycle's drive (where it bumped).

Optionally ``empty_sets``: how many updates so far left no hypothesis standing (the runner reports the share of
runs where that happened).

Estimators are listed by the id of the environment whose logs they read, in :mod:`polyenvs.estimators.table`
(name -> ``"module:Class"``, the paper's first); a user's own plugs in by import path:
``polyenvs localize --estimator mypackage.mymodule:MyLocalizer``.
"""

from __future__ import annotations

import inspect
from typing import Protocol, runtime_checkable

import numpy as np

from polyenvs.estimators.table import ESTIMATORS
from polyenvs.registry import bare_id, import_attribute

__all__ = ["DEFAULT_ENV_ID", "Estimator", "estimator_class", "estimator_kwargs", "estimators", "make_estimator"]

#: The environment whose logs the benchmark scores by default.
DEFAULT_ENV_ID = "polyenvs/BumperCartExplore-v2"


def estimators(env_id: str = DEFAULT_ENV_ID) -> dict[str, str]:
    """The estimators :mod:`polyenvs.estimators.table` lists for ``env_id``'s logs (a Gymnasium id, ``polyenvs:``
    prefix allowed): name -> ``"module:Class"``, the paper's first; none for any other environment."""
    return dict(ESTIMATORS.get(bare_id(env_id), {}))


@runtime_checkable
class Estimator(Protocol):
    """The estimator interface (see the module docstring)."""

    def reset(self, context, start_pose: np.ndarray, rng: np.random.Generator) -> None: ...

    def update(self, log: np.ndarray) -> np.ndarray: ...


def estimator_class(name: str, env_id: str = DEFAULT_ENV_ID) -> type:
    """The class behind one of ``env_id``'s estimators or a ``"module:Class"`` path; ``ValueError`` naming the
    choices if none."""
    known = estimators(env_id)
    path = known.get(name, name)
    if ":" not in path:
        raise ValueError(f"unknown estimator {name!r}; choose from {sorted(known)} or give 'module:Class'")
    try:
        cls = import_attribute(path)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ValueError(f"estimator {name!r}: cannot import {path!r} ({exc})") from None
    if not (callable(getattr(cls, "reset", None)) and callable(getattr(cls, "update", None))):
        raise ValueError(f"estimator {name!r}: {path} has no reset() and update() methods")
    return cls


def estimator_kwargs(name: str, kwargs: dict, env_id: str = DEFAULT_ENV_ID) -> dict:
    """``kwargs`` without ``particles`` if the estimator does not take it (only sampling estimators do, and the
    command line's ``--particles`` applies to those); every other keyword is passed on and checked by the class."""
    accepted = inspect.signature(estimator_class(name, env_id)).parameters
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values())
    if "particles" in kwargs and "particles" not in accepted and not takes_any:
        return {k: v for k, v in kwargs.items() if k != "particles"}
    return dict(kwargs)


def make_estimator(name: str, env_id: str = DEFAULT_ENV_ID, **kwargs) -> Estimator:
    """Build one of ``env_id``'s estimators or a ``"module:Class"`` (``particles`` dropped where not taken:
    :func:`estimator_kwargs`); ``ValueError`` for an unknown name or bad parameters."""
    cls = estimator_class(name, env_id)
    kwargs = estimator_kwargs(name, kwargs, env_id)
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ValueError(f"bad parameters for estimator {name!r}: {exc}") from None
