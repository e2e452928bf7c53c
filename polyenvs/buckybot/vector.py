"""Native vector environments: many Buckybots in one process, stepped by the single env's own compiled kernels.

``gym.make_vec("polyenvs/BuckybotWallFollow-v0", num_envs=1024)`` builds one: the task class itself, constructed
with 1024 rows (see :mod:`polyenvs.buckybot.env`), behind Gymnasium's ``VectorEnv`` API with next-step autoreset.
With ``num_envs=1`` it reproduces the single environment's first episode bit for bit for the same seed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from polyenvs.buckybot.env import BuckybotEnv
from polyenvs.buckybot.explore import BuckybotExploreEnv
from polyenvs.buckybot.goal import BuckybotGoalEnv
from polyenvs.buckybot.wall_follow import BuckybotWallFollowEnv

__all__ = ["BuckybotExploreVectorEnv", "BuckybotGoalVectorEnv", "BuckybotVectorEnv", "BuckybotWallFollowVectorEnv"]


class BuckybotVectorEnv(VectorEnv):
    """``num_envs`` robots of one Buckybot task on one fixed floor plan.

    Args:
        num_envs: number of robots (sub-environments).
        max_episode_steps: truncate each robot's episode after this many steps (``None``: never).
        **kwargs: the task's constructor arguments (``floor_plan`` must not be ``"random"``).

    Observations ``(num_envs, D)``, rewards, terminated and truncated ``(num_envs,)``. ``info`` holds
    ``action_mask`` ``(num_envs, 3)``, ``blocked`` and the ``reward_*`` terms ``(num_envs,)``, and, for the robots
    whose episode ended at this step, ``episode_metrics`` (a dict of ``(num_envs,)`` arrays, nan elsewhere) with
    its mask ``_episode_metrics``. Rendering is per single environment: build one with ``gym.make``.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: The single-robot task class whose batched core this vector env drives.
    env_class: type[BuckybotEnv] = BuckybotEnv

    def __init__(
        self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None, **kwargs
    ):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if max_episode_steps is not None and (
            not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1
        ):
            raise ValueError(f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}")
        if render_mode is not None:
            raise ValueError("render_mode: vector Buckybot envs do not render; render a gym.make(...) env instead")
        # The task class built with num_envs rows: the same validation, spaces and kernels as the single env.
        core = self.env_class.__new__(self.env_class)
        core._batch_size = int(num_envs)
        core.__init__(**kwargs)
        self._core = core
        self.num_envs = int(num_envs)
        self.max_episode_steps = max_episode_steps
        self.render_mode = None
        self.single_action_space = core.action_space
        self.action_space = batch_space(core.action_space, self.num_envs)
        self.single_observation_space = core.observation_space
        self.observation_space = batch_space(core.observation_space, self.num_envs)
        self.observation_structure = core.observation_structure
        self._rows = np.arange(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._actions = np.zeros(self.num_envs, dtype=np.int64)
        self._started = False

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._core._np_random = self.np_random  # one generator for every robot, as the single env has one
        self._core._reset_rows(self._rows, dict(options or {}))
        self._needs_reset[:] = False
        self._started = True
        return self._core._get_observations().copy(), self._info(np.zeros(self.num_envs, dtype=bool))

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions)
        if (
            actions.shape != (self.num_envs,)
            or actions.dtype.kind not in "iu"
            or (actions < 0).any()
            or (actions > 2).any()
        ):
            raise ValueError(f"actions must be {self.num_envs} integers in {{0, 1, 2}}, got {actions!r}")
        core = self._core
        restart = self._needs_reset
        acting = self._rows
        self._actions[:] = actions
        if restart.any():
            acting = self._rows[~restart]
            core._reset_rows(self._rows[restart], {})
            self._actions[restart] = -1  # these robots start a new episode: they neither move nor score
        core._advance(self._actions, core.np_random.standard_normal((self.num_envs, 9)), acting)
        rewards = core._rewards.sum(axis=1)
        terminated = core._terminated & ~restart
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = (core.steps >= self.max_episode_steps) & ~terminated & ~restart
        done = terminated | truncated
        self._needs_reset = done
        return core._get_observations().copy(), rewards, terminated, truncated, self._info(done)

    def _info(self, done: np.ndarray) -> dict[str, Any]:
        core = self._core
        info: dict[str, Any] = {
            "action_mask": core.sim.tip_allowed.astype(np.int8),
            "blocked": core.last_blocked.copy(),
        }
        for j, key in enumerate(core._reward_keys):
            info[key] = core._rewards[:, j].copy()
        if done.any():
            rows = np.flatnonzero(done)
            per_row = [core._episode_metrics(int(row)) for row in rows]  # only the few robots that just finished
            metrics = {name: np.full(self.num_envs, np.nan) for name in per_row[0]}
            for row, values in zip(rows, per_row, strict=True):
                for name, value in values.items():
                    metrics[name][row] = value
            info["episode_metrics"] = metrics
            info["_episode_metrics"] = done.copy()
        return info


class BuckybotWallFollowVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.wall_follow.BuckybotWallFollowEnv` (same arguments)."""

    env_class = BuckybotWallFollowEnv


class BuckybotExploreVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.explore.BuckybotExploreEnv` (same arguments)."""

    env_class = BuckybotExploreEnv


class BuckybotGoalVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.goal.BuckybotGoalEnv` (same arguments; no reset options)."""

    env_class = BuckybotGoalEnv
