"""The beasts' native vector env: ``gym.make_vec("polyenvs/BeastRoll-v1", num_envs=8)`` steps its MuJoCo models on
threads.

``num_envs`` environments of one beast id, each the id's own env (its model, its generator, its reset), whose
packed state (:class:`polyenvs.beast.kernel.Rows`) is one row of the vector env's batch. A step is one compiled call
per thread (:func:`polyenvs.beast.kernel.step_rows`, compiled ``nogil``) over that thread's contiguous slice of the
batch: the servos, ``mj_step``, the sensors, the rewards and the metrics of every environment in it, with the GIL
released, so ``threads`` threads step at once. A reset runs the env's own ``reset``. It is the id's class's
``VectorEnv`` (``BeastRollEnv.VectorEnv``: :class:`BeastVectorEnv` bound to it, :mod:`polyenvs.core.vector_entry`).

It gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit (each environment's MuJoCo state is its own
and is stepped by the same C function), in either of Gymnasium's autoreset modes: sub-env ``i`` reset with seed
``s`` is ``gym.make(id)`` reset with seed ``s + i``, through autoresets; ``max_episode_steps`` truncates as
Gymnasium's ``TimeLimit`` does; ``info`` carries the single env's keys in the vector convention
(:func:`polyenvs.core.rows.vector_convention`: ``episode_metrics`` on the rows whose episode ended, the time limit
included). It does not render (render ``gym.make(id)``).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from polyenvs.beast import kernel as KR
from polyenvs.core.jit import compiled_for
from polyenvs.core.rows import BatchVectorEnv, vector_convention
from polyenvs.core.validation import check_int, real_array, show

__all__ = ["MAX_THREADS", "BeastVectorEnv"]

#: The most threads a beast vector env steps on.
MAX_THREADS = 1024


class BeastVectorEnv(BatchVectorEnv):
    """``num_envs`` environments of one beast id, stepped on ``threads`` threads (see the module docstring).

    Args:
        num_envs: sub-environments (1-1,000,000).
        max_episode_steps: truncate each sub-environment's episode after this many steps (``None``: never).
        render_mode: ``None`` (the vector env does not render).
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` or ``AutoresetMode.SAME_STEP``.
        threads: threads that step the batch, each a contiguous slice of it (1-1,024; default ``os.cpu_count()``;
            more threads than environments run one environment each). The results do not depend on it.
        **kwargs: the id's keywords (``polyhedron``, ``layouts``, ...), as ``gym.make(id, **kwargs)`` takes them.
    """

    #: The beast task this vector env runs (``BeastRollEnv.VectorEnv`` is this class bound to it).
    env_class: type
    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        threads: int | None = None,
        **kwargs,
    ):
        self.threads = check_int("threads", (os.cpu_count() or 1) if threads is None else threads, 1, MAX_THREADS)
        super().__init__(num_envs, max_episode_steps, render_mode, autoreset_mode, **kwargs)

    def _build(self, num_envs, render_mode, kwargs):
        # The id's own envs, so that validation, models, generators and resets are gym.make's.
        envs = [self.env_class(**kwargs) for _ in range(num_envs)]
        first = envs[0]
        if not first.task_kind:
            raise ValueError(f"{self.env_class.__name__}'s rules are Python (_task_step): it has no native vector env")
        rows = KR.allocate_rows(num_envs, first.n_joints, first.observation_space.shape[0], len(first.metric_names))
        for e, env in enumerate(envs):
            env._join_rows(rows, e)
        self._envs, self._rows = envs, rows
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._active = np.ones(num_envs, dtype=bool)
        self._actions = np.zeros((num_envs, first.n_joints))
        self.observation_structure = first.observation_structure
        self.reward_names, self.metric_names = first.reward_names, first.metric_names
        self._reward_keys = tuple(f"reward_{name}" for name in first.reward_names)
        self._start_threads()
        return (first.observation_space, first.action_space), first.metadata["render_fps"]

    def _start_threads(self) -> None:
        """The batch's slices, one per thread, the compiled step for them and the threads (none for one slice)."""
        n = self._active.shape[0]
        bounds = np.linspace(0, n, min(self.threads, n) + 1).round().astype(int).tolist()
        parts = [(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        self._slices = [
            (self._active[a:b], self._actions[a:b], *(array[a:b] for array in self._rows)) for a, b in parts
        ]
        self._step = compiled_for(KR.step_rows, *self._slices[0])
        self._pool = ThreadPoolExecutor(len(parts) - 1, "beast-step") if len(parts) > 1 else None

    def __getstate__(self):
        state = self.__dict__.copy()
        for name in ("_slices", "_step", "_pool"):  # views, machine code and threads: rebuilt
            del state[name]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        for e, env in enumerate(self._envs):  # each env unpickled its own copy of its row: join the batch again
            env._join_rows(self._rows, e)
        self._start_threads()

    def _reset_rows(self, seeds, options) -> None:
        # The first env checks the options before anything changes; they are the same for every env.
        for env, seed in zip(self._envs, seeds, strict=True):
            env.reset(seed=seed, options=options)
        self._steps[:] = 0
        self._rows.out[:] = 0.0

    def _restart(self, rows) -> None:
        for e in rows:
            self._envs[e].reset()
        self._steps[rows] = 0
        self._rows.out[rows] = 0.0  # a restarted row reports its reset's info: zero terms

    def _check_batch_actions(self, actions) -> np.ndarray:
        values = real_array("actions", actions)
        if values.shape != self._actions.shape or not (np.abs(values) <= 1.0).all():
            raise ValueError(
                f"actions must be an array of shape {self._actions.shape} in [-1, 1] without NaN, got {show(actions)}"
            )
        return values

    def _advance_rows(self, actions, restart) -> None:
        if restart.any():  # next-step autoreset: these environments only start their new episode
            self._restart(np.flatnonzero(restart).tolist())
        np.logical_not(restart, out=self._active)
        self._actions[:] = actions
        # The other threads take a slice each and this one the first: one hand-over fewer than a pool of all.
        others = [self._pool.submit(self._step, *part) for part in self._slices[1:]] if self._pool else []
        self._step(*self._slices[0])
        for future in others:
            future.result()
        self._steps += self._active

    def _step_result(self, restart):
        out = self._rows.out
        return out[:, KR.REWARD_SUM].copy(), out[:, KR.TERMINATED] > 0.5, out[:, KR.DIVERGED] > 0.5

    def _row_steps(self) -> np.ndarray:
        return self._steps

    def _observations(self) -> np.ndarray:
        return self._rows.obs

    def _info(self, ended: np.ndarray) -> dict[str, Any]:
        out, metrics = self._rows.out, self._rows.metrics
        values: dict[str, Any] = {key: out[:, KR.TERMS + k].copy() for k, key in enumerate(self._reward_keys)}
        values["sim_unstable"] = out[:, KR.DIVERGED] > 0.5
        return vector_convention(values, {name: metrics[:, j] for j, name in enumerate(self.metric_names)}, ended)

    def render(self):
        """Nothing: this vector env does not render (``render_mode`` is ``None``; render ``gym.make(id)``)."""
        self._check_open()

    def close(self, **kwargs):
        if not self._closed:
            if self._pool is not None:
                self._pool.shutdown()
            for env in self._envs:
                env.close()
            self._closed = True
