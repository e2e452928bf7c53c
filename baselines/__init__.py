"""The papers' hand algorithms as policies with Stable-Baselines3's ``predict`` interface.

``make_policy(name, env_id, ...)`` builds any policy of an environment (a Gymnasium id or a PettingZoo module
path): ``"random"``, every hand baseline its row in :mod:`polyenvs.registry` lists, and ``"paper"``, an alias for
the environment's main paper algorithm (:mod:`baselines.factory`); or, given a path (a
training directory or a ``.zip``), a trained Stable-Baselines3 model behind the same interface
(:mod:`baselines.trained`).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from baselines.base import Policy, RandomPolicy
from baselines.factory import available_policies, make_baseline, paper_policy

if TYPE_CHECKING:  # a trained model is a policy too, but loading one needs polyenvs[train]
    from baselines.trained import TrainedPolicy

__all__ = ["Policy", "RandomPolicy", "available_policies", "make_policy", "paper_policy"]


def make_policy(
    name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs
) -> Policy | TrainedPolicy:
    """Build policy ``name`` for ``env_id``; raises ``ValueError`` naming the choices for an unknown name.

    ``name`` may also be a trained model's path (a training directory or a ``.zip``): see
    :func:`baselines.trained.load_trained_policy`, whose errors (``TrainedModelError``) are ``ValueError`` too.
    """
    from polyenvs.registry import bare_id

    env_id = bare_id(env_id)
    name = os.fspath(name)
    if name not in available_policies(env_id):
        from baselines.trained import is_model_path, load_trained_policy

        if is_model_path(name):
            return load_trained_policy(name, env_id, observation_space, action_space, seed=seed, **kwargs)
    return make_baseline(name, env_id, observation_space, action_space, seed=seed, **kwargs)
