"""The papers' hand algorithms as policies with Stable-Baselines3's ``predict`` interface.

``make_policy(name, env)`` builds any policy registered for an environment id: ``"random"``, every hand baseline
of that environment, and ``"paper"``, an alias for the environment's main paper algorithm; or, given a path (a
training directory or a ``.zip``), a trained Stable-Baselines3 model behind the same interface
(:mod:`baselines.trained`).
"""

from __future__ import annotations

import os
from collections.abc import Callable

from baselines.base import Policy, RandomPolicy

__all__ = ["POLICIES", "PAPER_POLICY", "Policy", "RandomPolicy", "available_policies", "make_policy"]


def _buckybot(cls_name: str, **defaults) -> Callable:
    def factory(observation_space, action_space, **kwargs):
        from baselines import buckybot

        return getattr(buckybot, cls_name)(observation_space, action_space, **{**defaults, **kwargs})

    return factory


#: env id -> policy name -> factory(observation_space, action_space, **kwargs). "random" is always available.
POLICIES: dict[str, dict[str, Callable]] = {
    "polyenvs/BuckybotWallFollow-v0": {
        "wall_follower": _buckybot("WallFollower"),
        "wall_follower_rules": _buckybot("WallFollower", x_s_cm=30.0, no_backtrack=True, clockwise_exception=True),
    },
    "polyenvs/BuckybotExplore-v0": {
        "wall_follow_explorer": _buckybot("WallFollowExplorer"),
    },
    "polyenvs/BuckybotGoal-v0": {
        "goal_seeker": _buckybot("GoalSeeker"),
    },
}

#: The paper's main algorithm for each environment, reachable as policy "paper".
PAPER_POLICY: dict[str, str] = {
    "polyenvs/BuckybotWallFollow-v0": "wall_follower",
    "polyenvs/BuckybotExplore-v0": "wall_follow_explorer",
    "polyenvs/BuckybotGoal-v0": "goal_seeker",
}


def _bare_id(env_id: str) -> str:
    return env_id.split(":", 1)[-1]


def available_policies(env_id: str) -> list[str]:
    """Policy names usable with ``env_id``: "random", its hand baselines, and "paper" where it has one."""
    env_id = _bare_id(env_id)
    names = ["random", *POLICIES.get(env_id, {})]
    return names + (["paper"] if env_id in PAPER_POLICY else [])


def make_policy(name: str, env_id: str, observation_space, action_space, seed: int | None = None, **kwargs) -> Policy:
    """Build policy ``name`` for ``env_id``; raises ``ValueError`` naming the choices for an unknown name.

    ``name`` may also be a trained model's path (a training directory or a ``.zip``): see
    :func:`baselines.trained.load_trained_policy`, whose errors (``TrainedModelError``) are ``ValueError`` too.
    """
    env_id = _bare_id(env_id)
    name = os.fspath(name)
    if name not in available_policies(env_id):
        from baselines.trained import is_model_path, load_trained_policy

        if is_model_path(name):
            return load_trained_policy(name, env_id, observation_space, action_space, **kwargs)
    if name == "paper":
        if env_id not in PAPER_POLICY:
            raise ValueError(f"{env_id} has no paper baseline; choose from {available_policies(env_id)}")
        name = PAPER_POLICY[env_id]
    if name == "random":
        if kwargs:
            raise ValueError(f"policy 'random' takes no parameters, got {sorted(kwargs)}")
        return RandomPolicy(observation_space, action_space, seed=seed)
    factories = POLICIES.get(env_id, {})
    if name not in factories:
        raise ValueError(
            f"unknown policy {name!r} for {env_id}; choose from {available_policies(env_id)} "
            "or give a trained model's path (a training directory or a .zip)"
        )
    try:
        return factories[name](observation_space, action_space, **kwargs)
    except TypeError as exc:
        raise ValueError(f"bad parameters for policy {name!r}: {exc}") from None
