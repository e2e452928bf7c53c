"""A batched swarm: E environments of N robots as one Gymnasium vector environment of E x N robots, for training
with parameter sharing (one policy acting on every robot's own observation), as SuperSuit's
``pettingzoo_env_to_vec_env_v1`` + ``concat_vec_envs_v1`` would give, but with one compiled call per kernel for
all E x N robots instead of one Python object per environment.

It is the PettingZoo environment's own core, :class:`polyenvs.swarm.batch.SwarmBatch`, built with E environments
instead of one: the task (a name of the registry's swarm modules, a :class:`~polyenvs.swarm.env.SwarmEnv` subclass
or instance) gives the validated parameters and the episodes, and nothing here knows which task it is.

Rows: robot ``r`` of environment ``e`` is row ``e * N + r``. Environment ``e`` reset with seed ``s`` is the
PettingZoo environment reset with seed ``s + e``, bit for bit, through autoresets (its generator makes the same
draws in the same order: the episode, the drift, the first readings; then per step the wheels' and sensors'
normals and the IR floor), so every result can be checked against the single environment.

Robots that arrive leave their environment's episode as in PettingZoo; their rows then read zero observations
and zero rewards until the environment's episode ends (SuperSuit's "black death"). An environment's episode ends
when all its robots have left (every row terminated) or after ``max_cycles`` steps (rows still in the episode
truncated, rows that left terminated); it is then reset in the same step (``autoreset_mode`` SAME_STEP): the rows
show the new episode's first observation and ``info["final_obs"]`` the last one, and
``info["final_info"]["episode_metrics"]`` holds, on the rows of the environments that ended, their swarm metrics
(``SwarmEnv.episode_metrics``): Gymnasium's same-step convention, which SB3-style adapters translate.
"""

from __future__ import annotations

import importlib

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from polyenvs.core.validation import check_int, check_options, real_array, show
from polyenvs.registry import REGISTRY
from polyenvs.swarm.batch import SwarmBatch
from polyenvs.swarm.env import SwarmEnv

__all__ = ["SwarmVectorEnv", "make_task", "task_names"]


def task_names() -> dict[str, str]:
    """The registry's swarm modules: short name (``"corridor_v0"``) -> module path."""
    rows = (row for row in REGISTRY if row.kind == "pettingzoo" and row.family == "swarm")
    return {row.id.rsplit(".", 1)[1]: row.id for row in rows}


def make_task(task, kwargs: dict) -> SwarmEnv:
    """The task a batch runs: a registry swarm module's name (short, ``"corridor_v0"``, or its module path) or a
    :class:`~polyenvs.swarm.env.SwarmEnv` subclass, built with ``kwargs``, or a ``SwarmEnv`` instance (then no
    ``kwargs``)."""
    if isinstance(task, SwarmEnv):
        if kwargs:
            raise ValueError(f"task: a SwarmEnv instance takes no keywords, got {sorted(kwargs)}")
        return task
    if isinstance(task, type) and issubclass(task, SwarmEnv):
        return task(**kwargs)
    names = task_names()
    if isinstance(task, str) and (task in names or task in names.values()):
        return importlib.import_module(names.get(task, task)).parallel_env(**kwargs)
    raise ValueError(f"task must be one of {sorted(names)}, a SwarmEnv subclass or a SwarmEnv, got {show(task)}")


class SwarmVectorEnv(VectorEnv):
    """``num_envs`` swarm environments of ``n_robots`` robots each, as ``num_envs * n_robots`` rows.

    Args:
        task: "corridor_v0", "obstacle_field_v0" or "formation_v0" (a swarm module of the registry, by name or
            module path), a :class:`~polyenvs.swarm.env.SwarmEnv` subclass, or a ``SwarmEnv`` (then no keywords).
        num_envs: environments in the batch (1-65536).
        **kwargs: the task's keywords (``n_robots``, ``max_cycles``, noise, platform ...; no ``render_mode``).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, task="corridor_v0", num_envs: int = 16, **kwargs):
        task = make_task(task, kwargs)
        self.n_envs = check_int("num_envs", num_envs, 1, 65536)
        if task.render_mode is not None:
            raise ValueError("render_mode: the batched swarm does not render; render a single environment")
        #: The task: its parameters (``task.platform``, ``task.max_cycles``, ...) and episodes.
        self.task = task
        self.batch = SwarmBatch(task, self.n_envs)
        self.n_robots = task.n_robots
        self.num_envs = self.n_envs * self.n_robots
        self.single_observation_space = task.observation_space("robot_0")
        self.single_action_space = task.action_space("robot_0")
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.max_cycles = task.max_cycles
        self._started = False  # step() needs a first reset()

    @property
    def pose(self) -> np.ndarray:
        """``(num_envs, 3)`` true poses of every row (the simulation's own array)."""
        return self.batch.pose

    @property
    def active(self) -> np.ndarray:
        """``(num_envs,)`` uint8: 1 while the row's robot is in its environment's episode (the simulation's own)."""
        return self.batch.active

    # --- Gymnasium VectorEnv API ------------------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        """Reset every environment; environment ``e`` gets seed ``seed + e`` (a list gives one seed per
        environment, or one per row, of which environment e takes row ``e * n_robots``'s). The swarm takes no
        reset options: ``options`` must be ``None`` or ``{}`` (anything else raises and changes nothing)."""
        check_options(options, ())
        e = self.n_envs
        if seed is None:
            seeds = [None] * e
        elif isinstance(seed, (list, tuple)):
            if len(seed) == self.num_envs:  # one per row (an SB3 adapter's): environment e takes its first row's
                seed = seed[:: self.n_robots]
            if len(seed) != e:
                raise ValueError(f"seed: {len(seed)} seeds for {e} environments ({self.num_envs} rows)")
            seeds = list(seed)
        else:
            seeds = [check_int("seed", seed, 0) + i for i in range(e)]
        self.batch.reset(range(e), [seeding.np_random(s)[0] for s in seeds])
        self._started = True
        return self.batch.observations.copy(), {}

    def step(self, actions):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        e, n = self.n_envs, self.n_robots
        command = real_array("actions", actions)  # complex, bool, string and object input refused, not cast
        if command.shape != (self.num_envs, 2) or not (np.abs(command) <= 1.0).all():
            raise ValueError(f"actions must be an array of shape ({self.num_envs}, 2) in [-1, 1] without NaN")
        batch = self.batch
        batch.step(command)
        obs = batch.observations
        rewards = batch.rewards.sum(axis=1)
        left = (batch.active == 0).reshape(e, n)
        truncated_env = batch.cycles >= self.max_cycles
        done_env = left.all(axis=1) | truncated_env
        infos = {}
        row_terminated = (left & done_env[:, None]).reshape(-1)
        row_truncated = (~left & truncated_env[:, None]).reshape(-1)
        if done_env.any():
            rows = np.repeat(done_env, n)
            infos["final_obs"] = np.where(rows[:, None], obs, 0.0).astype(np.float32)
            infos["_final_obs"] = rows
            metrics = batch.env_metrics()
            episode = {k: np.where(rows, np.repeat(v, n), 0.0) for k, v in metrics.items()}
            infos["final_info"] = {"episode_metrics": episode, "_episode_metrics": rows}
            infos["_final_info"] = rows
            batch.reset(np.flatnonzero(done_env))
        return batch.observations.copy(), rewards, row_terminated, row_truncated, infos
