"""Native vector envs of the single-robot swarm ids: ``gym.make_vec("polyenvs/APLiteCorridor-v0", num_envs=1024)``.

E swarms of one robot as one :class:`~polyenvs.swarm.batch.SwarmBatch` of E environments, the core that
``gym.make(id)`` (through the PettingZoo environment) runs with one: one noise draw per environment and one compiled
call per kernel per step for all E robots. It is the id's class's ``VectorEnv``
(``APLiteCorridorEnv.VectorEnv``: :class:`SingleRobotVectorEnv` bound to it, :mod:`polyenvs.core.vector_entry`).

It gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either of Gymnasium's autoreset modes
(``autoreset_mode=AutoresetMode.NEXT_STEP``, the default, or ``SAME_STEP``, with ``info["final_obs"]`` and
``info["final_info"]``): sub-env ``i`` reset with seed ``s`` is ``gym.make(id)`` reset with seed ``s + i``, through
autoresets; ``max_episode_steps`` truncates as Gymnasium's ``TimeLimit`` does (also on the step that terminates);
``info`` carries the single env's per-step keys in the vector convention (an array per key, with its ``_key``
mask; ``pose``, ``nearest_obstacle_cm`` and ``motor_powers`` read-only views of the simulation, valid until the
next step or reset), and ``episode_metrics``, a dict of arrays, on the rows whose episode ended this step, time
limit included (:func:`polyenvs.core.rows.vector_convention`). It does not render (render ``gym.make(id)``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from polyenvs.core.rows import vector_convention
from polyenvs.swarm.batched import SwarmBatchVectorEnv

__all__ = ["SingleRobotVectorEnv"]


class SingleRobotVectorEnv(SwarmBatchVectorEnv):
    """``num_envs`` single-robot swarm environments of one id (see the module docstring).

    Args:
        num_envs: sub-environments (1-1,000,000).
        max_episode_steps: truncate each sub-environment's episode after this many steps (``None``: never).
        render_mode: ``None`` (the vector env does not render).
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` or ``AutoresetMode.SAME_STEP``.
        **kwargs: the single-robot id's keywords (those of its swarm task, without ``n_robots`` and ``max_cycles``).
    """

    #: The single-robot env class this vector env runs (``APLiteCorridorEnv.VectorEnv`` is this class bound to it).
    env_class: type[gym.Env]
    action_dtype = np.float32

    def _build(self, num_envs, render_mode, kwargs):
        # The single env's own swarm of one: the same validation and parameters as gym.make(id).
        return self._run(self.env_class(**kwargs).swarm, num_envs)

    def _info(self, ended: np.ndarray) -> dict[str, Any]:
        info, metrics = self.batch.robot_columns()
        return vector_convention(info, metrics, ended)
