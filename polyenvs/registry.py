"""Every polyenvs Gymnasium id, in one flat table (the pattern of ``gymnasium/envs/__init__.py``).

Importing :mod:`polyenvs` registers them. Variants are constructor keywords (``gym.make(id, floor_plan="office")``),
not new ids. Entry points are strings, so nothing heavy is imported until an environment is made.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym

__all__ = ["ENV_IDS", "EnvEntry", "REGISTRY", "register_all"]


@dataclass(frozen=True)
class EnvEntry:
    id: str
    entry_point: str
    max_episode_steps: int
    family: str
    description: str
    kwargs: dict = field(default_factory=dict)
    #: A native vector env (``gym.make_vec(id, num_envs=N)``), where the family has one.
    vector_entry_point: str | None = None


REGISTRY: tuple[EnvEntry, ...] = (
    EnvEntry(
        id="polyenvs/BuckybotWallFollow-v0",
        entry_point="polyenvs.buckybot.wall_follow:BuckybotWallFollowEnv",
        vector_entry_point="polyenvs.buckybot.vector:BuckybotWallFollowVectorEnv",
        max_episode_steps=500,
        family="buckybot",
        description="Buckybot follows the nearest wall counter-clockwise at distance d* with six range finders",
    ),
    EnvEntry(
        id="polyenvs/BuckybotExplore-v0",
        entry_point="polyenvs.buckybot.explore:BuckybotExploreEnv",
        vector_entry_point="polyenvs.buckybot.vector:BuckybotExploreVectorEnv",
        max_episode_steps=1000,
        family="buckybot",
        description="Buckybot sweeps an unknown office with its range finders; dead-reckoned map error reported",
    ),
    EnvEntry(
        id="polyenvs/BuckybotGoal-v0",
        entry_point="polyenvs.buckybot.goal:BuckybotGoalEnv",
        vector_entry_point="polyenvs.buckybot.vector:BuckybotGoalVectorEnv",
        max_episode_steps=300,
        family="buckybot",
        description="Buckybot reaches a goal given by dead-reckoned bearing and distance without hitting walls",
    ),
)

ENV_IDS: list[str] = [entry.id for entry in REGISTRY]


def register_all() -> None:
    """Register every id with Gymnasium (idempotent: re-importing does not warn about overrides)."""
    for entry in REGISTRY:
        if entry.id not in gym.registry:
            gym.register(
                id=entry.id,
                entry_point=entry.entry_point,
                vector_entry_point=entry.vector_entry_point,
                max_episode_steps=entry.max_episode_steps,
                kwargs=dict(entry.kwargs),
            )


def entry(env_id: str) -> EnvEntry:
    """The registry row of ``env_id`` (``polyenvs:`` module prefix allowed)."""
    env_id = env_id.split(":", 1)[-1]
    for row in REGISTRY:
        if row.id == env_id:
            return row
    raise KeyError(env_id)
