"""Policies by name: ``"random"``, the hand baselines an environment's row in :mod:`polyenvs.registry` lists, and
``"paper"``, an alias for the environment's main paper algorithm.

:func:`baselines.make_policy` takes these names and a trained model's path; the residual composer
(:mod:`baselines.residual`) builds its base from here, below the trained models that load it.
"""

from __future__ import annotations

import inspect

from baselines.base import Policy, RandomPolicy

__all__ = ["available_policies", "make_baseline", "paper_policy"]


def _row(env_id: str):
    from polyenvs.registry import entry

    try:
        return entry(env_id)
    except KeyError:
        return None


def paper_policy(env_id: str) -> str | None:
    """The name of ``env_id``'s paper algorithm (what policy ``"paper"`` stands for), or ``None``."""
    row = _row(env_id)
    return row.paper if row is not None else None


def available_policies(env_id: str) -> list[str]:
    """Policy names usable with ``env_id``: "random", its hand baselines, and "paper" where it has one."""
    row = _row(env_id)
    names = ["random", *(b.name for b in row.baselines)] if row is not None else ["random"]
    return names + (["paper"] if row is not None and row.paper else [])


def make_baseline(name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs) -> Policy:
    """Build policy ``name`` (one of :func:`available_policies`) for ``env_id``; raises ``ValueError`` naming the
    choices for an unknown name (the choices :func:`baselines.make_policy` offers, a trained model's path among
    them) or rejected parameters."""
    from polyenvs.registry import bare_id, import_attribute

    env_id = bare_id(env_id)
    if name == "paper":
        paper = paper_policy(env_id)
        if paper is None:
            raise ValueError(f"{env_id} has no paper baseline; choose from {available_policies(env_id)}")
        name = paper
    if name == "random":
        if kwargs:
            raise ValueError(f"policy 'random' takes no parameters, got {sorted(kwargs)}")
        return RandomPolicy(observation_space, action_space, seed=seed)
    row = _row(env_id)
    baselines = {b.name: b for b in row.baselines} if row is not None else {}
    if name not in baselines:
        raise ValueError(
            f"unknown policy {name!r} for {env_id}; choose from {available_policies(env_id)} "
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
