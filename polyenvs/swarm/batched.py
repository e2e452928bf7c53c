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

The seeding and the autoreset are the shared ones of :class:`polyenvs.core.rows.BatchVectorEnv`, with an environment
of N rows where the other families have one; :class:`SwarmBatchVectorEnv` is that base over a ``SwarmBatch``, which
the single-robot ids' native vector env (:mod:`polyenvs.swarm.vector`) shares.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode

from polyenvs.core.rows import BatchVectorEnv, vector_convention
from polyenvs.core.validation import check_options, real_array, show
from polyenvs.registry import REGISTRY
from polyenvs.swarm.batch import SwarmBatch
from polyenvs.swarm.env import RobotRows, SwarmEnv

__all__ = ["SwarmBatchVectorEnv", "SwarmVectorEnv", "make_task", "task_names"]


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


class SwarmBatchVectorEnv(RobotRows, BatchVectorEnv):
    """The shared :class:`~polyenvs.core.rows.BatchVectorEnv` over a :class:`~polyenvs.swarm.batch.SwarmBatch`:
    each environment ``n_robots`` rows, ending when all its robots have left (terminated) or at the task's
    ``max_cycles`` (the robots still in it truncated). A subclass's ``_build`` makes the task and returns
    :meth:`_run`'s result; it gives ``_info()``."""

    #: The precision actions are read at before they drive the wheels (the single env reads float32).
    action_dtype: type[np.floating] = np.float64

    def _run(self, task: SwarmEnv, num_envs: int):
        """Batch ``num_envs`` environments of ``task``; one row's spaces and the frame rate, as ``_build`` returns."""
        #: The task: its parameters (``task.platform``, ``task.max_cycles``, ...) and episodes.
        self.task = task
        self.batch = SwarmBatch(task, num_envs)
        self.rows_per_env = task.n_robots
        self.observation_structure = task.observation_structure
        self.reward_names = task.reward_names
        spaces = (task.observation_space("robot_0"), task.action_space("robot_0"))
        return spaces, task.metadata["render_fps"]

    def _reset_rows(self, seeds, options) -> None:
        check_options(options, ())
        current = self.batch.generators
        generators = [
            current[e] if s is None and current[e] is not None else seeding.np_random(s)[0] for e, s in enumerate(seeds)
        ]
        self.batch.reset(range(len(seeds)), generators)

    def _restart(self, rows) -> None:
        self.batch.reset(sorted({row // self.rows_per_env for row in rows}))

    def _check_batch_actions(self, actions) -> np.ndarray:
        """The ``(num_envs, 2)`` motor powers, as float64 of their ``action_dtype`` values."""
        values = real_array("actions", actions, self.action_dtype)  # complex, bool, string and object refused
        if values.shape != (self.num_envs, 2) or not (np.abs(values) <= 1.0).all():
            raise ValueError(f"actions must be an array of shape ({self.num_envs}, 2) in [-1, 1] without NaN")
        return values.astype(np.float64, copy=False)

    def _advance_rows(self, actions, restart) -> None:
        if restart.any():  # next-step autoreset: these environments only start their new episode
            restarting = restart[:: self.rows_per_env]
            self.batch.reset(np.flatnonzero(restarting))
            self.batch.step(actions, ~restarting)
        else:
            self.batch.step(actions)

    def _step_result(self, restart):
        batch = self.batch
        left = (batch.active == 0).reshape(-1, self.rows_per_env)
        truncated = batch.cycles >= self.task.max_cycles  # the swarm's own cap
        done = left.all(axis=1) | truncated
        terminated_rows = (left & done[:, None]).reshape(-1)
        truncated_rows = (~left & truncated[:, None]).reshape(-1)
        return batch.rewards.sum(axis=1), terminated_rows, truncated_rows

    def _row_steps(self) -> np.ndarray:
        return np.repeat(self.batch.cycles, self.rows_per_env)

    def _observations(self) -> np.ndarray:
        return self.batch.observations

    def render(self):
        """Nothing: this vector env does not render (``render_mode`` is ``None``; render a single environment)."""
        self._check_open()
        return None

    def close(self, **kwargs):
        self._closed = True


class SwarmVectorEnv(SwarmBatchVectorEnv):
    """``num_envs`` swarm environments of ``n_robots`` robots each, as ``num_envs * n_robots`` rows.

    Args:
        task: "corridor_v0", "obstacle_field_v0" or "formation_v0" (a swarm module of the registry, by name or
            module path), a :class:`~polyenvs.swarm.env.SwarmEnv` subclass, or a ``SwarmEnv`` (then no keywords).
        num_envs: environments in the batch (1-1,000,000).
        **kwargs: the task's keywords (``n_robots``, ``max_cycles``, noise, platform ...; no ``render_mode``).

    ``reset(seed=s)`` seeds environment ``e`` with ``s + e`` (a list: one seed per environment, or one per row, of
    which environment e takes its first row's; without a seed, each environment continues its own generator); the
    swarm takes no reset options. ``info`` is empty but at the end of an environment's episode (see the module
    docstring).
    """

    def __init__(self, task="corridor_v0", num_envs: int = 16, **kwargs):
        super().__init__(num_envs, max_episode_steps=None, autoreset_mode=AutoresetMode.SAME_STEP, task=task, **kwargs)

    def _build(self, num_envs, render_mode, kwargs):
        task = make_task(kwargs.pop("task"), kwargs)
        if task.render_mode is not None:
            raise ValueError("render_mode: the batched swarm does not render; render a single environment")
        self.n_envs, self.n_robots, self.max_cycles = num_envs, task.n_robots, task.max_cycles
        return self._run(task, num_envs)

    def _info(self, ended: np.ndarray) -> dict[str, Any]:
        return {}  # per-step info for every robot would cost more than the step at this scale

    def _final_info(self, done: np.ndarray) -> dict[str, Any]:
        """Each finished environment's swarm metrics (``SwarmEnv.episode_metrics``), on each of its rows."""
        metrics = {name: np.repeat(value, self.n_robots) for name, value in self.batch.env_metrics().items()}
        return vector_convention({}, metrics, done)
