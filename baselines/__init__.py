"""The papers' hand algorithms as policies with Stable-Baselines3's ``predict`` interface.

``make_policy(name, env_id, ...)`` builds any policy of an environment (a Gymnasium id or a PettingZoo module
path): ``"random"``, every hand baseline its row in :mod:`baselines.table` lists, and ``"paper"``, an alias for
the environment's main paper algorithm (:mod:`baselines.factory`); or, given a path (a training directory or a
``.zip``), a trained Stable-Baselines3 model behind the same interface (:mod:`baselines.trained`).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from baselines.base import Policy, RandomPolicy
from baselines.factory import available_policies, build_baseline, paper_policy, policy_names
from baselines.table import hand_baselines
from polyenvs.registry import bare_id

if TYPE_CHECKING:  # a trained model is a policy too, but loading one needs polyenvs[train]
    from baselines.trained import TrainedPolicy
    from baselines.tuned import TunedPolicy

__all__ = ["Policy", "RandomPolicy", "available_policies", "make_policy", "paper_policy"]


def make_policy(
    name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs
) -> Policy | TrainedPolicy | TunedPolicy:
    """Build policy ``name`` for ``env_id``; raises ``ValueError`` naming the choices for an unknown name.

    ``name`` may also be a trained model's path (a training directory or a ``.zip``): see
    :func:`baselines.trained.load_trained_policy`, whose errors (``TrainedModelError``) are ``ValueError`` too; or
    a tuned baseline's directory (``polyenvs tune``'s): see :func:`baselines.tuned.load_tuned_policy`.
    """
    env_id = bare_id(env_id)
    name = os.fspath(name)
    row = hand_baselines(env_id)  # looked up once, for the names and the build
    if name not in policy_names(row):
        from baselines.tuned import is_tuned_path, load_tuned_policy

        if is_tuned_path(name):
            return load_tuned_policy(name, env_id, observation_space, action_space, seed=seed, **kwargs)
        from baselines.trained import is_model_path, load_trained_policy

        if is_model_path(name):
            return load_trained_policy(name, env_id, observation_space, action_space, seed=seed, **kwargs)
    return build_baseline(name, env_id, row, observation_space, action_space, seed=seed, **kwargs)
