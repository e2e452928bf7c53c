"""One robot of the swarm tasks as a Gymnasium environment: ``polyenvs/APLiteCorridor-v0`` and
``polyenvs/APLiteObstacleField-v0``, on the same core and task code as the PettingZoo modules (a swarm of one)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from polyenvs.swarm.corridor_v0 import CorridorEnv
from polyenvs.swarm.obstacle_field_v0 import ObstacleFieldEnv

__all__ = ["APLiteCorridorEnv", "APLiteObstacleFieldEnv"]

#: The time limit is the registry's ``max_episode_steps``; the swarm itself never truncates a single robot.
_NO_LIMIT = 1_000_000


class _SingleRobot(gym.Env):
    swarm_class: type = CorridorEnv
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(self, **kwargs):
        if "n_robots" in kwargs or "max_cycles" in kwargs:
            raise ValueError(
                "n_robots and max_cycles are fixed in the single-robot environment (use max_episode_steps)"
            )
        self.swarm = self.swarm_class(n_robots=1, max_cycles=_NO_LIMIT, **kwargs)
        self.render_mode = self.swarm.render_mode
        self.metadata = {**self.metadata, "render_fps": self.swarm.metadata["render_fps"]}
        self.observation_space = self.swarm.observation_space("robot_0")
        self.action_space = self.swarm.action_space("robot_0")
        self.observation_structure = self.swarm.observation_structure
        self.reward_names = self.swarm.reward_names
        self._done = True

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        obs, infos = self.swarm.reset(seed=seed, options=options)
        self._done = False
        return obs["robot_0"], infos["robot_0"]

    def step(self, action):
        if self._done:
            raise gym.error.ResetNeeded("the robot has arrived: call reset()")
        obs, rewards, terminations, _, infos = self.swarm.step({"robot_0": np.asarray(action)})
        self._done = terminations["robot_0"]
        return obs["robot_0"], rewards["robot_0"], terminations["robot_0"], False, infos["robot_0"]

    def render(self):
        return self.swarm.render()

    def close(self):
        self.swarm.close()


class APLiteCorridorEnv(_SingleRobot):
    __doc__ = (
        "One X80Pro in the corridor (``corridor_v0`` with one robot; the paper's experiment).\n\n"
        + (CorridorEnv.__doc__ or "").split("\n", 1)[1]
    )
    swarm_class = CorridorEnv


class APLiteObstacleFieldEnv(_SingleRobot):
    __doc__ = (
        "One Maxelbot in the obstacle field (``obstacle_field_v0`` with one robot).\n\n"
        + (ObstacleFieldEnv.__doc__ or "").split("\n", 1)[1]
    )
    swarm_class = ObstacleFieldEnv
