"""Native vector environments: many Buckybots in one process, stepped by the single env's own compiled kernels.

``gym.make_vec("polyenvs/BuckybotWallFollow-v0", num_envs=1024)`` builds one: the task class itself, constructed
with 1024 rows (see :mod:`polyenvs.buckybot.env`), behind Gymnasium's ``VectorEnv`` API with next-step autoreset.

It gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either of Gymnasium's autoreset modes
(``autoreset_mode=AutoresetMode.NEXT_STEP``, the default, or ``SAME_STEP``, with ``info["final_obs"]`` and
``info["final_info"]``, which Stable-Baselines3-style training needs): row ``i`` reset with seed ``s`` draws from the
generator a single env reset with seed ``s + i`` would have (:mod:`polyenvs.core.streams`), through autoresets;
``info`` carries the single env's keys in the vector convention (an array per key, with its ``_key`` mask;
``episode_metrics`` is a dict of arrays); ``floor_plan="random"`` draws a room per row. Only the speed differs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.error import ClosedEnvironmentError, ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.env import _ACTUATOR_NAMES, _SENSOR_FACES, BuckybotEnv, copy_generator
from polyenvs.buckybot.explore import BuckybotExploreEnv
from polyenvs.buckybot.goal import BuckybotGoalEnv
from polyenvs.buckybot.wall_follow import BuckybotWallFollowEnv
from polyenvs.core.validation import check_int, show

__all__ = ["BuckybotExploreVectorEnv", "BuckybotGoalVectorEnv", "BuckybotVectorEnv", "BuckybotWallFollowVectorEnv"]


def _object_table(rows: list[list]) -> np.ndarray:
    table = np.empty((len(rows), len(rows[0])), dtype=object)
    for i, row in enumerate(rows):
        for j, value in enumerate(row):
            table[i, j] = value
    return table


_ACTUATOR_TABLE = _object_table(_ACTUATOR_NAMES)
_SENSOR_FACE_TABLE = _object_table(_SENSOR_FACES)


class BuckybotVectorEnv(VectorEnv):
    """``num_envs`` robots of one Buckybot task.

    Args:
        num_envs: number of robots (sub-environments).
        max_episode_steps: truncate each robot's episode after this many steps (``None``: never).
        render_mode: ``"rgb_array"`` renders sub-environment 0.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (a finished robot restarts at the next step, which then only
            resets it) or ``AutoresetMode.SAME_STEP`` (it restarts within the step that finished it; the last
            observation and info are in ``info["final_obs"]`` and ``info["final_info"]``).
        **kwargs: the task's constructor arguments.

    Observations ``(num_envs, D)``, rewards, terminated and truncated ``(num_envs,)``; ``info`` as described above.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4, "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: The single-robot task class whose batched core this vector env drives.
    env_class: type[BuckybotEnv] = BuckybotEnv

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs,
    ):
        num_envs = check_int("num_envs", num_envs, 1, 1_000_000)
        try:
            autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {show(autoreset_mode)}") from None
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {show(autoreset_mode)}")
        if max_episode_steps is not None:
            max_episode_steps = check_int("max_episode_steps", max_episode_steps, 1)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be 'rgb_array' or None for a vector env, got {show(render_mode)}")
        # The task class built with num_envs rows: the same validation, spaces and kernels as the single env.
        core = self.env_class.__new__(self.env_class)
        core._batch_size = num_envs
        core.__init__(render_mode=render_mode, **kwargs)
        self._core = core
        self.metadata = {**self.metadata, "autoreset_mode": autoreset_mode}
        self.autoreset_mode = autoreset_mode
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.single_action_space = core.action_space
        self.action_space = batch_space(core.action_space, num_envs)
        self.single_observation_space = core.observation_space
        self.observation_space = batch_space(core.observation_space, num_envs)
        self.observation_structure = core.observation_structure
        self._needs_reset = np.zeros(num_envs, dtype=bool)
        self._actions = np.zeros(num_envs, dtype=np.int64)
        self._started = False
        self._closed = False

    def _check_open(self) -> None:
        if self._closed:
            raise ClosedEnvironmentError("this vector env is closed")

    def _row_generators(self, seed) -> list[tuple[np.random.Generator, bool]]:
        """Row i's generator for this reset, as ``SyncVectorEnv`` seeds sub-environment i, and whether it is a
        new seed's."""
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        elif isinstance(seed, (list, tuple)) and len(seed) == n:
            seeds = list(seed)
        else:
            raise ValueError(f"seed must be None, an int or a list of {n} ints/None, got {show(seed)}")
        generators = []
        for row, s in enumerate(seeds):
            current = self._core.sim.streams.generators[row]
            if s is None and current is not None:
                generators.append((copy_generator(current), False))
            else:
                generators.append((seeding.np_random(s)[0], True))
        return generators

    def reset(self, *, seed=None, options: dict[str, Any] | None = None):
        self._check_open()
        core = self._core
        options = core._check_options(options)
        generators = self._row_generators(seed)
        prepared = [core._prepare_row(row, rng, options, new) for row, (rng, new) in enumerate(generators)]  # may raise
        core._commit_rows(prepared)
        self._needs_reset[:] = False
        self._started = True
        return core._observations.copy(), self._info()

    def step(self, actions):
        self._check_open()
        if not self._started:
            raise ResetNeeded("call reset() before step()")
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
        self._actions[:] = actions
        if restart.any():
            rows = np.flatnonzero(restart)
            generators = core.sim.streams.generators
            core._commit_rows([core._prepare_row(int(row), generators[row], {}, False) for row in rows])
            self._actions[restart] = -1  # these robots start a new episode: they neither move nor score
        core._advance(self._actions)
        if core._trail is not None and not restart[0]:
            core._trail.append(core.sim.state[0, S.X : S.Y + 1], core.sim.state[0, S.DR_X : S.DR_Y + 1])
        out = core._out
        rewards = out[:, core._reward_column].copy()
        terminated = out[:, core._terminated_column] > 0.5
        terminated &= ~restart
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = (core.sim.state[:, S.STEPS] >= self.max_episode_steps) & ~terminated & ~restart
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP or not done.any():
            self._needs_reset = done
            return core._observations.copy(), rewards, terminated, truncated, self._info()
        # Same-step autoreset: keep what the finished robots saw, restart them now, report both.
        final_obs = np.full(self.num_envs, None, dtype=object)
        for row in np.flatnonzero(done).tolist():
            final_obs[row] = core._observations[row].copy()
        final_info = _only_rows(self._info(), done)
        generators = core.sim.streams.generators
        core._commit_rows([core._prepare_row(row, generators[row], {}, False) for row in np.flatnonzero(done).tolist()])
        info = self._info()
        info["final_obs"], info["_final_obs"] = final_obs, done.copy()
        info["final_info"], info["_final_info"] = final_info, done.copy()
        return core._observations.copy(), rewards, terminated, truncated, info

    def render(self):
        """Sub-environment 0's frame."""
        self._check_open()
        if self.render_mode is None:
            return None
        if not self._started:
            raise ResetNeeded("call reset() before render()")
        return self._core.render()

    def close(self, **kwargs):
        if not self._closed:
            self._core.close()
            self._closed = True

    def _info(self) -> dict[str, Any]:
        """The single env's info for every row, in Gymnasium's vector convention.

        Array entries are views of two fresh arrays (the ground-truth block and the reward/metric block), and every
        ``_key`` mask is the same read-only all-true array: every row reports every key at every step.
        """
        core = self._core
        state = core.sim.state
        truth = state[:, S.INFO_START : S.INFO_STOP].copy()
        scores = core._out[:, : core._reward_column].copy()
        face, edge0 = state[:, S.FACE].astype(np.intp), state[:, S.EDGE0].astype(np.intp)

        def block(column: int, width: int = 0) -> np.ndarray:
            start = column - S.INFO_START
            return truth[:, start] if width == 0 else truth[:, start : start + width]

        values: dict[str, Any] = {
            "action_mask": state[:, S.ALLOWED : S.ALLOWED + 3].astype(np.int8),
            "face": face + 1,
            "heading_deg": block(S.POSE_INFO + 2),
            "tip_directions_deg": block(S.TIP_DIRECTIONS, 3),
            "actuators": _ACTUATOR_TABLE[face, edge0],
            "sensor_faces": _SENSOR_FACE_TABLE[face, edge0],
            "pose": block(S.POSE_INFO, 3),
            "dead_reckoned_pose": block(S.DR_POSE_INFO, 3),
            "true_range_cm": block(S.TRUE_RANGE, 6),
            "wall_distance_cm": block(S.WALL_DISTANCE),
            "blocked": state[:, S.BLOCKED] > 0.5,
        }
        k = len(core._reward_keys)
        for j, key in enumerate(core._reward_keys):
            values[key] = scores[:, j]
        values.update(core._vector_task_info())
        every_row = np.ones(self.num_envs, dtype=bool)
        every_row.flags.writeable = False
        metrics: dict[str, Any] = {}
        for j, name in enumerate(core._metric_names):
            metrics[name] = scores[:, k + j]
            metrics[f"_{name}"] = every_row
        values["episode_metrics"] = metrics
        info: dict[str, Any] = {}
        for key, value in values.items():
            info[key] = value
            info[f"_{key}"] = every_row
        return info


def _only_rows(info: dict[str, Any], rows: np.ndarray) -> dict[str, Any]:
    """``info`` (vector convention) for ``rows`` only, as ``SyncVectorEnv`` collects a same-step ``final_info``:
    other rows zero (``None`` in object arrays) and every ``_key`` mask equal to ``rows``."""
    kept: dict[str, Any] = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        if isinstance(value, dict):
            kept[key] = _only_rows(value, rows)
        else:
            array = np.full(value.shape, None, dtype=object) if value.dtype == object else np.zeros_like(value)
            array[rows] = value[rows]
            kept[key] = array
        kept[f"_{key}"] = rows.copy()
    return kept


class BuckybotWallFollowVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.wall_follow.BuckybotWallFollowEnv` (same arguments)."""

    env_class = BuckybotWallFollowEnv


class BuckybotExploreVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.explore.BuckybotExploreEnv` (same arguments)."""

    env_class = BuckybotExploreEnv


class BuckybotGoalVectorEnv(BuckybotVectorEnv):
    """Vector form of :class:`~polyenvs.buckybot.goal.BuckybotGoalEnv` (same arguments and reset options)."""

    env_class = BuckybotGoalEnv
