"""One robot of the swarm tasks as a Gymnasium environment: ``polyenvs/APLiteCorridor-v0`` and
``polyenvs/APLiteObstacleField-v0``, on the same core and task code as the PettingZoo modules.

A single robot is not a swarm of one: the PettingZoo environment inside (``env.swarm``, one robot) validates the
keywords, draws the episodes and renders, but a step skips its agents' dictionaries and runs the core's compiled
step (:func:`polyenvs.swarm.batch.step_kernel`: move, sense, reward terms, metrics, termination) in one call on its
batch of one, then reads the robot's row. So each step is, bit for bit, that robot's step in the swarm.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.error import ResetNeeded

from polyenvs.core.validation import check_options
from polyenvs.core.vector_entry import NativeVector
from polyenvs.swarm.batch import INFO_DISTANCE, INFO_REWARD, INFO_TERMS, INFO_TURN_DEG
from polyenvs.swarm.corridor_v0 import CorridorEnv
from polyenvs.swarm.env import VERSION_HISTORY_V0, SwarmEnv
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
        self._reward_keys = tuple(f"reward_{name}" for name in self.reward_names)
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
        obs, _ = self.swarm.reset(seed=seed, options=options)
        self._started, self._done = True, False
        return obs["robot_0"], self._info(self.swarm.batch.info_table[0].tolist())

    def step(self, action):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        if self._done:
            raise ResetNeeded(f"{self._ended_by}: call reset()")
        batch = self.swarm.batch
        batch.command[0] = self._command(action)
        batch.step()
        terminated = bool(batch.terminated[0])
        truncated = not terminated and int(batch.cycles[0]) >= self.swarm.max_cycles
        table = batch.info_table[0].tolist()
        info = self._info(table)
        if terminated or truncated:
            self._done = True
            self._ended_by = "the robot has arrived" if terminated else "the episode was truncated"
            info["episode_metrics"] = self.episode_metrics()
        if self.render_mode == "human":
            self.swarm.render()
        return batch.observations[0].copy(), table[INFO_REWARD], terminated, truncated, info

    def _command(self, action):
        """The robot's power fractions: a real float array of shape (2,) in [-1, 1] read at float32, as the swarm
        reads it (the common case, checked here); anything else through the swarm's own checks, which name what is
        wrong (``ValueError``, nothing changed)."""
        if type(action) is np.ndarray and action.dtype.kind == "f" and action.shape == (2,):
            values = action.astype(np.float32)
            left, right = values.tolist()
            if -1.0 <= left <= 1.0 and -1.0 <= right <= 1.0:  # NaN fails
                return values
        return self.swarm._command({"robot_0": action})[0]

    def _info(self, table: list[float]) -> dict:
        """The robot's per-step info from its row of the swarm's info ``table`` (the swarm's per-robot keys,
        without ``episode_metrics``). Its arrays are fresh, not views of the simulation as in the PettingZoo env:
        Gymnasium's ``check_env`` refuses an info that shares memory with the next one."""
        batch = self.swarm.batch
        return {
            "pose": batch.pose[0].copy(),
            "collisions": int(batch.info_collisions[0]),
            "distance_to_goal_m": table[INFO_DISTANCE],
            "nearest_obstacle_cm": batch.nearest_cm[0].copy(),
            "motor_powers": batch.motor_powers[0].copy(),
            "turning_angle_deg": table[INFO_TURN_DEG],
            "stopped": bool(batch.info_stopped[0]),
            **dict(zip(self._reward_keys, table[INFO_TERMS:], strict=True)),
        }

    def episode_metrics(self) -> dict[str, float]:
        """The robot's episode metrics (the names of ``info["episode_metrics"]``): the current episode's so far,
        and after it ended the final ones, until the next reset. Gymnasium's ``TimeLimit`` truncates outside the
        env, whose last ``info`` then lacks them: read them here (``env.unwrapped.episode_metrics()``) or wrap the
        env in :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics`."""
        if not self._started:
            raise ResetNeeded("call reset() before episode_metrics()")
        return self.swarm.batch.robot_metrics_row(0)

    def render(self):
        return self.swarm.render()  # warns without a render_mode; raises ResetNeeded before the first reset

    def close(self):
        self.swarm.close()


#: The single-robot ids' Version History: the swarm tasks' v0, then the lean ``info`` (issue 33's wording).
VERSION_HISTORY = (
    VERSION_HISTORY_V0
    + """
- ``info`` made lean without changing an episode (2026-12-05): ``info["episode_metrics"]`` is only in the info of
  the step that ends the episode (terminated, or truncated by the env itself; on a native vector env's rows that
  end, time limit included), ``env.unwrapped.episode_metrics()`` returns them at any time, and
  :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates;
  on the native vector env ``pose``, ``nearest_obstacle_cm`` and ``motor_powers`` are read-only views valid until
  the next step or reset (copy them to keep them). A step is one compiled call (2026-12-05)."""
)


def _single_doc(first_line: str, swarm_class: type[SwarmEnv]) -> str:
    """A single-robot id's docstring: ``first_line``, the swarm task's documentation, this module's Version
    History."""
    body = (swarm_class.__doc__ or "").split("\n", 1)[1].split("## Version History")[0]
    return f"{first_line}\n\n{body}## Version History\n    " + VERSION_HISTORY.replace("\n", "\n    ") + "\n    "


class APLiteCorridorEnv(_SingleRobot):
    __doc__ = _single_doc(
        "One X80Pro in the corridor (``corridor_v0`` with one robot; the paper's experiment).", CorridorEnv
    )
    swarm_class = CorridorEnv


class APLiteObstacleFieldEnv(_SingleRobot):
    __doc__ = _single_doc(
        "One Maxelbot in the obstacle field (``obstacle_field_v0`` with one robot).", ObstacleFieldEnv
    )
    swarm_class = ObstacleFieldEnv
