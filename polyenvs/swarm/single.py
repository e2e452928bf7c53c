"""One robot of the swarm tasks as a Gymnasium environment: ``polyenvs/APLiteCorridor-v0`` and
``polyenvs/APLiteObstacleField-v0``, on the same core and task code as the PettingZoo modules (a swarm of one)."""

from __future__ import annotations

import gymnasium as gym
from gymnasium.error import ResetNeeded

from polyenvs.core.validation import check_options
from polyenvs.core.vector_entry import NativeVector
from polyenvs.swarm.corridor_v0 import CorridorEnv
from polyenvs.swarm.env import SwarmEnv
from polyenvs.swarm.obstacle_field_v0 import ObstacleFieldEnv
from polyenvs.swarm.vector import SingleRobotVectorEnv

__all__ = ["APLiteCorridorEnv", "APLiteObstacleFieldEnv", "single_robot_swarm"]

#: The time limit is the registry's ``max_episode_steps``. The swarm inside has a cap of its own (``max_cycles``
#: must be a number), far above any time limit; an episode run that long ends as a truncation (``truncated=True``),
#: and stepping on raises ``ResetNeeded``.
_NO_LIMIT = 1_000_000


def single_robot_swarm(swarm_class: type[SwarmEnv], kwargs: dict) -> SwarmEnv:
    """The swarm of one robot inside a single-robot id (and its vector env): ``n_robots`` and ``max_cycles`` are
    fixed (the time limit is ``max_episode_steps``)."""
    if "n_robots" in kwargs or "max_cycles" in kwargs:
        raise ValueError("n_robots and max_cycles are fixed in the single-robot environment (use max_episode_steps)")
    return swarm_class(n_robots=1, max_cycles=_NO_LIMIT, **kwargs)


class _SingleRobot(gym.Env):
    swarm_class: type[SwarmEnv] = CorridorEnv
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    #: Each id's native vector env (``gym.make_vec``): ``APLiteCorridorEnv.VectorEnv``.
    VectorEnv = NativeVector(SingleRobotVectorEnv)

    def __init__(self, **kwargs):
        self.swarm = single_robot_swarm(self.swarm_class, kwargs)
        self.render_mode = self.swarm.render_mode
        self.metadata = {**self.metadata, "render_fps": self.swarm.metadata["render_fps"]}
        self.observation_space = self.swarm.observation_space("robot_0")
        self.action_space = self.swarm.action_space("robot_0")
        self.observation_structure = self.swarm.observation_structure
        self.reward_names = self.swarm.reward_names
        self._started = False
        self._done = True
        self._ended_by = ""

    @property
    def layout_split(self):
        """How ``layouts=`` splits the task's layouts (the swarm task's)."""
        return self.swarm.layout_split

    def episode_layout(self) -> dict:
        """The episode's layout as :attr:`layout_split` classifies it (the swarm task's)."""
        return self.swarm.episode_layout()

    def reset(self, *, seed=None, options=None):
        check_options(options, ())  # before anything changes, the seeding below included
        super().reset(seed=seed)
        obs, infos = self.swarm.reset(seed=seed, options=options)
        self._started, self._done = True, False
        return obs["robot_0"], infos["robot_0"]

    def step(self, action):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        if self._done:
            raise ResetNeeded(f"{self._ended_by}: call reset()")
        obs, rewards, terminations, truncations, infos = self.swarm.step({"robot_0": action})
        terminated, truncated = terminations["robot_0"], truncations["robot_0"]
        if terminated or truncated:
            self._done = True
            self._ended_by = "the robot has arrived" if terminated else "the episode was truncated"
        return obs["robot_0"], rewards["robot_0"], terminated, truncated, infos["robot_0"]

    def render(self):
        return self.swarm.render()  # warns without a render_mode; raises ResetNeeded before the first reset

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
