"""Native vector envs of the single-robot swarm ids: ``gym.make_vec("polyenvs/APLiteCorridor-v0", num_envs=1024)``.

E swarms of one robot as one :class:`~polyenvs.swarm.batch.SwarmBatch` of E environments, the core that
``gym.make(id)`` (through the PettingZoo environment) runs with one: one noise draw per environment and one compiled
call per kernel per step for all E robots.

It gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either of Gymnasium's autoreset modes
(``autoreset_mode=AutoresetMode.NEXT_STEP``, the default, or ``SAME_STEP``, with ``info["final_obs"]`` and
``info["final_info"]``): sub-env ``i`` reset with seed ``s`` is ``gym.make(id)`` reset with seed ``s + i``, through
autoresets; ``max_episode_steps`` truncates as Gymnasium's ``TimeLimit`` does (also on the step that terminates);
``info`` carries the single env's keys in the vector convention (an array per key, with its ``_key`` mask;
``episode_metrics`` a dict of arrays). It does not render (render ``gym.make(id)``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding

from polyenvs.core.rows import BatchVectorEnv, vector_convention
from polyenvs.core.validation import check_options, real_array
from polyenvs.swarm.batch import SwarmBatch
from polyenvs.swarm.corridor_v0 import CorridorEnv
from polyenvs.swarm.env import SwarmEnv
from polyenvs.swarm.obstacle_field_v0 import ObstacleFieldEnv
from polyenvs.swarm.single import single_robot_swarm

__all__ = ["APLiteCorridorVectorEnv", "APLiteObstacleFieldVectorEnv", "SingleRobotVectorEnv"]


class SingleRobotVectorEnv(BatchVectorEnv):
    """``num_envs`` single-robot swarm environments (see the module docstring).

    Args:
        num_envs: sub-environments (1-1,000,000).
        max_episode_steps: truncate each sub-environment's episode after this many steps (``None``: never).
        render_mode: ``None`` (the vector env does not render).
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` or ``AutoresetMode.SAME_STEP``.
        **kwargs: the single-robot id's keywords (those of its swarm task, without ``n_robots`` and ``max_cycles``).
    """

    #: The swarm task of the id (set by each subclass).
    swarm_class: type[SwarmEnv] = CorridorEnv

    def _build(self, num_envs, render_mode, kwargs):
        #: The task (one robot): its parameters and episodes.
        self.task = single_robot_swarm(self.swarm_class, kwargs)
        self.batch = SwarmBatch(self.task, num_envs)
        self.observation_structure = self.task.observation_structure
        self.reward_names = self.task.reward_names
        spaces = (self.task.observation_space("robot_0"), self.task.action_space("robot_0"))
        return spaces, self.task.metadata["render_fps"]

    def _reset_rows(self, seeds, options) -> None:
        check_options(options, ())
        current = self.batch.generators
        generators = [
            current[i] if s is None and current[i] is not None else seeding.np_random(s)[0] for i, s in enumerate(seeds)
        ]
        self.batch.reset(range(self.num_envs), generators)

    def _restart(self, rows) -> None:
        self.batch.reset(rows)

    def _check_batch_actions(self, actions) -> np.ndarray:
        """The ``(num_envs, 2)`` powers as float64 of their float32 values (as the single env takes them)."""
        values = real_array("actions", actions, np.float32)  # complex, bool, string and object input refused
        if values.shape != (self.num_envs, 2) or not (np.abs(values) <= 1.0).all():
            raise ValueError(f"actions must be an array of shape ({self.num_envs}, 2) in [-1, 1] without NaN")
        return values.astype(np.float64)

    def _advance_rows(self, actions, restart) -> None:
        if restart.any():  # next-step autoreset: these sub-envs only start their new episode
            self.batch.reset(np.flatnonzero(restart))
            self.batch.step(actions, ~restart)
        else:
            self.batch.step(actions)

    def _step_result(self, restart):
        batch = self.batch
        terminated = batch.terminated > 0
        truncated = (batch.cycles >= self.task.max_cycles) & ~terminated  # the swarm's own cap
        return batch.rewards.sum(axis=1), terminated, truncated

    def _row_steps(self) -> np.ndarray:
        return self.batch.cycles

    def _observations(self) -> np.ndarray:
        return self.batch.observations

    def _info(self) -> dict[str, Any]:
        info, metrics = self.batch.robot_columns()
        return vector_convention(info, metrics, self.num_envs)

    def render(self):
        """Nothing: this vector env does not render (``render_mode`` is ``None``)."""
        self._check_open()
        return None

    def close(self, **kwargs):
        self._closed = True


class APLiteCorridorVectorEnv(SingleRobotVectorEnv):
    """Vector form of :class:`~polyenvs.swarm.single.APLiteCorridorEnv` (same keywords)."""

    swarm_class = CorridorEnv


class APLiteObstacleFieldVectorEnv(SingleRobotVectorEnv):
    """Vector form of :class:`~polyenvs.swarm.single.APLiteObstacleFieldEnv` (same keywords)."""

    swarm_class = ObstacleFieldEnv
