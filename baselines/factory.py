"""Policies by name: ``"random"``, the hand baselines an environment's row in :mod:`baselines.table` lists, and
``"paper"``, an alias for the environment's main paper algorithm.

:func:`baselines.make_policy` takes these names and a trained model's path; the residual composer
(:mod:`baselines.residual`) builds its base from here, below the trained models that load it. The public functions
take an environment id and look its row up once; :func:`policy_names` and :func:`build_baseline` take the row, for
callers that already hold it.
"""

from __future__ import annotations

import dataclasses
import inspect

from baselines.base import Policy, RandomPolicy
from baselines.table import HandBaselines, hand_baselines
from polyenvs.registry import bare_id, import_attribute

__all__ = [
    "TunableParameter",
    "available_policies",
    "build_baseline",
    "make_baseline",
    "paper_policy",
    "policy_names",
    "tunable_parameters",
]


@dataclasses.dataclass(frozen=True)
class TunableParameter:
    """A constructor parameter of a hand baseline that ``polyenvs tune`` searches: its range, unit and source (the
    policy class's :attr:`~baselines.base.Policy.tunables`), and ``start``, the value the baseline runs with (its
    row's fixed keyword where it sets one, else the constructor's default: the paper's value)."""

    name: str
    low: float
    high: float
    start: float
    unit: str
    source: str


def paper_policy(env_id: str) -> str | None:
    """The name of ``env_id``'s paper algorithm (what policy ``"paper"`` stands for), or ``None``."""
    return hand_baselines(env_id).paper


def available_policies(env_id: str) -> list[str]:
    """Policy names usable with ``env_id``: "random", its hand baselines, and "paper" where it has one."""
    return policy_names(hand_baselines(env_id))


def policy_names(row: HandBaselines) -> list[str]:
    """:func:`available_policies` of the environment whose row is ``row``."""
    return ["random", *row.names, *(["paper"] if row.paper else [])]


def tunable_parameters(name: str, env_id: str) -> list[TunableParameter]:
    """The parameters ``polyenvs tune`` may search for baseline ``name`` (a hand baseline of ``env_id``, or
    ``"paper"``), in declaration order; empty for one that declares none. ``ValueError`` for an unknown name."""
    row = hand_baselines(env_id)
    baseline = _baseline(name, bare_id(env_id), row)
    tunables = import_attribute(baseline.factory).tunables
    if tunables is None:
        return []
    return [
        TunableParameter(
            f.name,
            low=f.metadata["range"][0],
            high=f.metadata["range"][1],
            start=float(baseline.kwargs.get(f.name, f.default)),
            unit=f.metadata["unit"],
            source=f.metadata["source"],
        )
        for f in dataclasses.fields(tunables)
        if "range" in f.metadata
    ]


def _baseline(name: str, env_id: str, row: HandBaselines):
    """The row's :class:`~baselines.table.Baseline` called ``name`` ("paper" for its paper algorithm)."""
    if name == "paper":
        if row.paper is None:
            raise ValueError(f"{env_id} has no paper baseline; choose from {policy_names(row)}")
        name = row.paper
    baselines = {b.name: b for b in row.baselines}
    if name not in baselines:
        raise ValueError(
            f"unknown policy {name!r} for {env_id}; choose from {policy_names(row)} "
            "or give a trained model's path (a training directory or a .zip)"
        )
    return baselines[name]


def make_baseline(name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs) -> Policy:
    """Build policy ``name`` (one of :func:`available_policies`) for ``env_id``; raises ``ValueError`` naming the
    choices for an unknown name (the choices :func:`baselines.make_policy` offers, a trained model's path among
    them) or rejected parameters."""
    return build_baseline(name, env_id, hand_baselines(env_id), observation_space, action_space, seed, **kwargs)


def build_baseline(
    name: str, env_id: str, row: HandBaselines, observation_space, action_space, seed: int | None = None, **kwargs
) -> Policy:
    """:func:`make_baseline` given ``env_id``'s row (``env_id`` only names the environment in errors)."""
    env_id = bare_id(env_id)
    if name == "random":
        if kwargs:
            raise ValueError(f"policy 'random' takes no parameters, got {sorted(kwargs)}")
        return RandomPolicy(observation_space, action_space, seed=seed)
    baseline = _baseline(name, env_id, row)
    try:
        factory = import_attribute(baseline.factory)
        kwargs = {**baseline.kwargs, **kwargs}
        if "seed" in inspect.signature(factory).parameters:  # stochastic baselines draw from their own seed
            kwargs.setdefault("seed", seed)
        return factory(observation_space, action_space, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad parameters for policy {name!r}: {exc}") from None
