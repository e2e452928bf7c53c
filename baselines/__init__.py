"""The papers' hand algorithms as policies with Stable-Baselines3's ``predict`` interface.

``make_policy(name, env_id, ...)`` builds any policy of an environment (a Gymnasium id or a PettingZoo module
path): ``"random"``, every hand baseline its row in :mod:`polyenvs.registry` lists, and ``"paper"``, an alias for
the environment's main paper algorithm; or, given a path (a
training directory or a ``.zip``), a trained Stable-Baselines3 model behind the same interface
(:mod:`baselines.trained`).
"""

from __future__ import annotations

import inspect
import os
from typing import TYPE_CHECKING

from baselines.base import Policy, RandomPolicy

if TYPE_CHECKING:  # a trained model is a policy too, but loading one needs polyenvs[train]
    from baselines.trained import TrainedPolicy

__all__ = ["Policy", "RandomPolicy", "available_policies", "make_policy", "paper_policy"]


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


def make_policy(
    name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs
) -> Policy | TrainedPolicy:
    """Build policy ``name`` for ``env_id``; raises ``ValueError`` naming the choices for an unknown name.

    ``name`` may also be a trained model's path (a training directory or a ``.zip``): see
    :func:`baselines.trained.load_trained_policy`, whose errors (``TrainedModelError``) are ``ValueError`` too.
    """
    from polyenvs.registry import bare_id, import_attribute

    env_id = bare_id(env_id)
    name = os.fspath(name)
    if name not in available_policies(env_id):
        from baselines.trained import is_model_path, load_trained_policy

        if is_model_path(name):
            return load_trained_policy(name, env_id, observation_space, action_space, seed=seed, **kwargs)
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
