"""The task's metrics on every step that ends an episode, time limits included (issue 33's lean ``info``).

A polyenvs env reports ``info["episode_metrics"]`` on the step that ends its episode as the env knows it
(terminated, or truncated by a budget of its own). Gymnasium's ``TimeLimit``, which ``gym.make`` wraps around it,
truncates from outside, so that step's info lacks them; :class:`RecordEpisodeMetrics` adds them there from
``env.unwrapped.episode_metrics()``, as ``RecordEpisodeStatistics`` adds its ``"episode"``::

    env = RecordEpisodeMetrics(gym.make("polyenvs/BuckybotGoal-v0"))
    ...
    observation, reward, terminated, truncated, info = env.step(action)
    if terminated or truncated:
        print(info["episode_metrics"])
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym

__all__ = ["RecordEpisodeMetrics"]


class RecordEpisodeMetrics(gym.Wrapper):
    """Puts ``info["episode_metrics"] = env.unwrapped.episode_metrics()`` on every terminated or truncated step whose
    info lacks it (a truncation by Gymnasium's ``TimeLimit``); other steps pass through unchanged.

    Args:
        env: a Gymnasium env whose unwrapped env has ``episode_metrics() -> dict[str, float]`` (every polyenvs env).
    """

    def __init__(self, env: gym.Env):
        if not callable(getattr(env.unwrapped, "episode_metrics", None)):
            raise ValueError(f"env must have an episode_metrics() method on its unwrapped env, got {env.unwrapped!r}")
        super().__init__(env)

    def step(self, action) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        if (terminated or truncated) and "episode_metrics" not in info:
            info["episode_metrics"] = self.env.unwrapped.episode_metrics()
        return observation, reward, terminated, truncated, info
