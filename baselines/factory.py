"""Policies by name: ``"random"``, the hand baselines an environment's row in :mod:`baselines.table` lists, and
``"paper"``, an alias for the environment's main paper algorithm.

:func:`baselines.make_policy` takes these names and a trained model's path; the residual composer
(:mod:`baselines.residual`) builds its base from here, below the trained models that load it. The public functions
take an environment id and look its row up once; :func:`policy_names` and :func:`build_baseline` take the row, for
callers that already hold it.
"""

from __future__ import annotations

import inspect

from baselines.base import Policy, RandomPolicy
from baselines.table import HandBaselines, hand_baselines
from polyenvs.registry import bare_id, import_attribute

__all__ = ["available_policies", "build_baseline", "make_baseline", "paper_policy", "policy_names"]


def paper_policy(env_id: str) -> str | None:
    """The name of ``env_id``'s paper algorithm (what policy ``"paper"`` stands for), or ``None``."""
    return hand_baselines(env_id).paper


def available_policies(env_id: str) -> list[str]:
    """Policy names usable with ``env_id``: "random", its hand baselines, and "paper" where it has one."""
    return policy_names(hand_baselines(env_id))


def policy_names(row: HandBaselines) -> list[str]:
    """:func:`available_policies` of the environment whose row is ``row``."""
    return ["random", *row.names, *(["paper"] if row.paper else [])]


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
    if name == "paper":
        if row.paper is None:
            raise ValueError(f"{env_id} has no paper baseline; choose from {policy_names(row)}")
        name = row.paper
    if name == "random":
        if kwargs:
            raise ValueError(f"policy 'random' takes no parameters, got {sorted(kwargs)}")
        return RandomPolicy(observation_space, action_space, seed=seed)
    baselines = {b.name: b for b in row.baselines}
    if name not in baselines:
        raise ValueError(
            f"unknown policy {name!r} for {env_id}; choose from {policy_names(row)} "
            "or give a trained model's path (a training directory or a .zip)"
        )
    try:
        factory = import_attribute(baselines[name].factory)
        kwargs = {**baselines[name].kwargs, **kwargs}
        if "seed" in inspect.signature(factory).parameters:  # stochastic baselines draw from their own seed
            kwargs.setdefault("seed", seed)
        return factory(observation_space, action_space, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad parameters for policy {name!r}: {exc}") from None
