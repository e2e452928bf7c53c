"""Batched-rows environments: one class that is a Gymnasium env as a batch of one and a native vector env as a
batch of many, so a family's equations exist once, in compiled kernels over packed arrays.

:class:`RowsEnv` is the single-agent Gymnasium surface; :class:`RowsVectorEnv` builds the same class with
``num_envs`` rows behind Gymnasium's ``VectorEnv`` API. A family subclasses :class:`RowsEnv` (Buckybot:
:class:`polyenvs.buckybot.env.BuckybotEnv`; the cart: :class:`polyenvs.bumper.env.BumperCartExploreEnv`) and provides
what follows. The hooks are underscore names, as Gymnasium's ``MujocoEnv`` hooks (``_get_obs``) are: they are the
protocol between a family and this base, documented here, not calls for users.

- a keyword-only constructor argument ``num_rows: int = 1``, passed first to :meth:`RowsEnv._use_rows`: the rows
  the instance simulates; ``gym.make`` builds one, :class:`RowsVectorEnv` builds ``num_envs`` (``cls(num_rows=n,
  **kwargs)``, the same validation, spaces and kernels as the single env);

- ``out_columns``: the task's declaration, the named columns (:class:`polyenvs.core.columns.OutColumns`) of the
  ``_out`` table its kernels write (reward terms, metrics, reward and terminated); ``reward_names`` and the metric
  names, and so ``info``'s keys, are read from it, so the kernels' columns and ``info`` cannot drift apart;
- in ``__init__``: ``action_space``, ``observation_space``, then :meth:`RowsEnv._allocate_rows` (the observation
  rows and the ``_out`` table), and :meth:`RowsEnv._pack_kernel` (what its compiled kernels take, as one
  :class:`polyenvs.core.jit.KernelArgs`: the simulator's tuple of arrays, ``_out`` and the task's tuple);
- ``_check_options(options)``: the validated reset options;
- ``_prepare_row(row, rng, options, reseeded)``: draw and validate one row's new episode on ``rng``, writing
  nothing (it may raise), and ``_commit_rows(prepared)``: install them (nothing in it raises), then observe;
- ``_advance(actions)``: step every row whose action is valid (a row given ``NO_ACTION`` was just reset: it neither
  moves nor scores);
- ``_row_generator(row)`` (the row's generator, ``None`` before its first reset), ``_row_steps()`` (steps into
  each row's episode, for time limits), ``_check_actions(actions)`` (a batch, for the vector env), and
  ``_get_info(row)`` / ``_vector_info(ended)`` (one row's per-step info; every row's, in the vector convention
  of :func:`vector_convention`, with the metrics of the rows in ``ended``);
- optionally ``_on_row0_step()`` (after row 0 moved: trails for rendering) and ``_make_renderer()`` (an object
  whose ``render(env)`` draws row 0 and ``close()`` closes its window), built at the first ``render()``;
- optionally ``budget_spent()`` and ``_row0_budget_spent()``: the rows whose episode has used a budget of its own
  (the cart's ``budget_cycles``), which the vector env truncates there, and the same for row 0 alone, as one
  Python bool, which the single env's ``step`` asks at every step; by default none.

The native vector env of a task is its class's ``VectorEnv`` (:class:`RowsVectorEnv` with ``env_class`` the task,
:mod:`polyenvs.core.vector_entry`): a task writes no vector class, its registry row says ``native_vector=True``.

Conventions every family inherits from here:

- *A call that raises changes nothing.* A reset is a transaction: options are validated and every random choice is
  drawn on a copy of the generator (:func:`copy_generator`) before anything is written.
- *Seeding as Gymnasium's.* ``reset(seed=s)`` restarts row 0 from a new generator; an unseeded reset continues the
  row's own. The vector env seeds row ``i`` with ``s + i``, as ``SyncVectorEnv`` seeds sub-environment ``i``, so it
  gives what ``SyncVectorEnv`` over ``gym.make(id)`` gives, bit for bit, in either autoreset mode.
- *A lean info* (issue 33). The per-step ``info`` holds what changes every step and costs little to hand over: the
  reward terms, the family's cheap keys and its ground truth, which the vector env hands over as a read-only view
  of the simulator's state (:func:`read_only`: made once, the same object every step, valid until the next step or
  reset; copy it to keep it). A single env copies its row: Gymnasium's checker (``gym.make``'s, and ``check_env``)
  refuses an info that shares memory with an earlier one. ``info["episode_metrics"]`` (the task's metrics, the
  ``_out`` table's metric columns) is only in the info of the step that ends the episode as the env knows it
  (terminated, or truncated by its budget); :meth:`RowsEnv.episode_metrics` returns them at any time, and
  :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates.
  The vector env, which applies the time limit itself, puts them on the rows whose episode ended
  (:func:`vector_convention`).
"""

from __future__ import annotations

import copy
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.error import ClosedEnvironmentError, ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from polyenvs.core.columns import OutColumns
from polyenvs.core.jit import KernelArgs
from polyenvs.core.validation import check_int, check_options, show
from polyenvs.core.vector_entry import NativeVector

__all__ = [
    "NO_ACTION",
    "BatchVectorEnv",
    "RowsEnv",
    "RowsVectorEnv",
    "check_autoreset_mode",
    "check_vector_arguments",
    "copy_generator",
    "only_rows",
    "read_only",
    "vector_convention",
]

#: The most rows one instance simulates (a vector env's ``num_envs`` has the same bound).
MAX_ROWS = 1_000_000

#: The action a row gets in the step that restarted it (next-step autoreset): it neither moves nor scores.
NO_ACTION = -1


def check_autoreset_mode(value) -> AutoresetMode:
    """A native vector env's ``autoreset_mode``: ``NEXT_STEP`` or ``SAME_STEP`` (an ``AutoresetMode`` or its
    value), else ``ValueError``."""
    try:
        mode = AutoresetMode(value)
    except ValueError:
        raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {show(value)}") from None
    if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {show(value)}")
    return mode


def check_vector_arguments(num_envs, max_episode_steps, autoreset_mode) -> tuple[int, int | None, AutoresetMode]:
    """The arguments every native vector env takes, checked: ``num_envs`` in [1, 1e6], ``max_episode_steps``
    None or >= 1, ``autoreset_mode`` (:func:`check_autoreset_mode`)."""
    num_envs = check_int("num_envs", num_envs, 1, MAX_ROWS)
    if max_episode_steps is not None:
        max_episode_steps = check_int("max_episode_steps", max_episode_steps, 1)
    return num_envs, max_episode_steps, check_autoreset_mode(autoreset_mode)


#: NumPy's bit generators, which a seed sequence builds and a ``state`` assignment puts anywhere.
_NUMPY_BIT_GENERATORS = (np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64)


def copy_generator(rng: np.random.Generator) -> np.random.Generator:
    """An independent generator in the same state (a reset draws on it and keeps it only if nothing raises).

    NumPy's own bit generators are rebuilt from their seed sequence and given the state (about a fifth of
    ``copy.deepcopy``'s time, which a single env's every reset paid); any other is deep-copied."""
    bit_generator = rng.bit_generator
    if type(bit_generator) not in _NUMPY_BIT_GENERATORS:
        return copy.deepcopy(rng)
    twin = type(bit_generator)(copy.copy(bit_generator.seed_seq))
    twin.state = bit_generator.state
    return np.random.Generator(twin)


def read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array``'s memory, to hand over in ``info`` without a copy: made once, it shows what the
    simulator holds now, so it is valid until the next step or reset (a consumer that keeps it copies it)."""
    view = array.view()
    view.flags.writeable = False
    return view


class RowsEnv(gym.Env):
    """Base class of batched-rows environments (see the module docstring for what a family provides)."""

    #: The task's declaration: its reward terms and metrics by name, laid out as the columns of the ``_out`` table
    #: the kernels write (made by the task's module); ``info``'s keys come from the same names.
    out_columns: OutColumns = OutColumns((), ())
    #: Rows this instance simulates (its ``num_rows``): 1 for ``gym.make``; :class:`RowsVectorEnv` builds more.
    _batch_size = 1
    #: Each task class's native vector env, ``TaskEnv.VectorEnv`` (set below, once :class:`RowsVectorEnv` exists).
    VectorEnv: ClassVar[NativeVector]

    @property
    def reward_names(self) -> tuple[str, ...]:
        """The reward terms, in the order of ``info`` (``reward_<name>``)."""
        return self.out_columns.terms

    @property
    def all_metric_names(self) -> tuple[str, ...]:
        """Every episode metric, the family's and the task's, in the order of ``info["episode_metrics"]``."""
        return self.out_columns.metrics

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The task's own metrics (a family whose base reports metrics of its own leaves those out)."""
        return self.all_metric_names

    def _use_rows(self, num_rows) -> None:
        """Simulate ``num_rows`` rows (checked: an integer in [1, 1,000,000]); a family's constructor calls this
        before it allocates anything."""
        self._batch_size = check_int("num_rows", num_rows, 1, MAX_ROWS)

    def _allocate_rows(self, action_dtype=np.int64, action_shape: tuple[int, ...] = ()) -> None:
        """The arrays the kernels write: observation rows and ``_out`` (the columns of ``out_columns``: reward
        terms, metrics, reward, terminated per row); and the actions batch."""
        columns = self.out_columns
        n = self._batch_size
        self._observations = np.zeros((n, *self.observation_space.shape), dtype=self.observation_space.dtype)
        self._out = np.zeros((n, columns.width))
        self._reward_column, self._terminated_column = columns.reward, columns.terminated
        self._reward_keys = tuple(f"reward_{name}" for name in columns.terms)
        self._metric_names = columns.metrics
        self._metric_slice = columns.metric_slice
        self._actions = np.zeros((n, *action_shape), dtype=action_dtype)
        self._row0 = np.zeros(1, dtype=np.int64)
        self._started = False

    def _pack_kernel(self, sim: tuple, task: tuple) -> None:
        """Pack what the compiled kernels take into ``self._kernel`` (``sim``, ``_out`` and ``task``); call it again
        after replacing one of those arrays."""
        self._kernel_parts = (sim, task)
        self._kernel = KernelArgs(sim, self._out, task)

    #: Attributes :meth:`_pack_kernel` builds from ``_kernel_parts``: compiled-code objects, never pickled.
    _packed_names: tuple[str, ...] = ("_kernel",)

    def __getstate__(self):
        state = self.__dict__.copy()
        for name in self._packed_names:  # compiled-code memory: rebuilt from its parts, which pickle with the env
            state.pop(name, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        if "_kernel_parts" in state:
            self._pack_kernel(*self._kernel_parts)

    # --- the family's part --------------------------------------------------------------------------------------
    def _check_options(self, options) -> dict:
        return check_options(options, ())

    def _prepare_row(self, row: int, rng: np.random.Generator, options: dict, reseeded: bool) -> Any:
        raise NotImplementedError

    def _commit_rows(self, prepared: list) -> None:
        raise NotImplementedError

    def _advance(self, actions: np.ndarray) -> None:
        raise NotImplementedError

    def _row_generator(self, row: int) -> np.random.Generator | None:
        raise NotImplementedError

    def _row_steps(self) -> np.ndarray:
        raise NotImplementedError

    def _check_action(self, action) -> Any:
        """One validated action for row 0 (raises ``ValueError``/``TypeError``, changing nothing)."""
        raise NotImplementedError

    def _check_actions(self, actions: np.ndarray) -> np.ndarray:
        """A validated batch of actions, one per row."""
        raise NotImplementedError

    def _get_info(self, row: int) -> dict[str, Any]:
        raise NotImplementedError

    def _vector_info(self, ended: np.ndarray) -> dict[str, Any]:
        raise NotImplementedError

    def _metric_rows(self) -> dict[str, np.ndarray]:
        """Every row's metrics so far, name -> a view of its ``_out`` column (for :func:`vector_convention`)."""
        out = self._out
        return {name: out[:, self._metric_slice.start + j] for j, name in enumerate(self._metric_names)}

    def _on_row0_step(self) -> None:
        """Called after row 0 moved (not after a restart): rendering trails."""

    def budget_spent(self) -> np.ndarray:
        """Per row, whether its episode has used a budget of its own (it ends there, truncated): none here."""
        return np.zeros(self._batch_size, dtype=bool)

    def _row0_budget_spent(self) -> bool:
        """:meth:`budget_spent` of row 0 alone, without building an array (the single env asks at every step)."""
        return False

    def _make_renderer(self):
        raise NotImplementedError

    _renderer = None

    # --- Gymnasium API ------------------------------------------------------------------------------------------
    def episode_metrics(self) -> dict[str, float]:
        """The task's metrics (``info["episode_metrics"]``' names): the current episode's so far, and after it ended
        the final ones, until the next reset. Gymnasium's ``TimeLimit`` truncates outside the env, whose last
        ``info`` then lacks them: read them here (``env.unwrapped.episode_metrics()``) or wrap the env in
        :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics`."""
        if not self._started:
            raise ResetNeeded("call reset() before episode_metrics()")
        return dict(zip(self._metric_names, self._out[0, self._metric_slice].tolist(), strict=True))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if self._batch_size != 1:
            raise TypeError(f"an env of num_rows={self._batch_size} is driven by a RowsVectorEnv, not reset() itself")
        options = self._check_options(options)
        if seed is not None:
            rng, used_seed = seeding.np_random(seed)
        else:
            rng, used_seed = copy_generator(self.np_random), self._np_random_seed
        self._commit_rows([self._prepare_row(0, rng, options, reseeded=seed is not None)])
        self._np_random, self._np_random_seed = rng, used_seed
        return self._observations[0].copy(), self._get_info(0)

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if not self._started:
            raise ResetNeeded("call reset() before render()")
        if self._renderer is None:
            self._renderer = self._make_renderer()
        return self._renderer.render(self)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def step(self, action):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        self._actions[0] = self._check_action(action)
        self._advance(self._actions)
        self._on_row0_step()
        out = self._out
        terminated = out.item(0, self._terminated_column) != 0.0
        truncated = self._row0_budget_spent()
        info = self._get_info(0)
        if terminated or truncated:
            info["episode_metrics"] = self.episode_metrics()
        return self._observations[0].copy(), out.item(0, self._reward_column), terminated, truncated, info


class BatchVectorEnv(VectorEnv):
    """Gymnasium's ``VectorEnv`` over a batch that steps every sub-environment in one call: the seeding, the time
    limit and both autoreset modes, written once for every family's native vector env.

    Its constructor takes ``num_envs``, ``max_episode_steps``, ``render_mode`` (one of ``metadata["render_modes"]``
    or ``None``) and ``autoreset_mode``, checks them, and hands the rest to the subclass's ``_build(num_envs,
    render_mode, kwargs)``, which builds the batch and returns one row's ``(observation_space, action_space)`` and
    its frame rate. A subclass also provides ``_check_batch_actions(actions)``, ``_reset_rows(seeds, options)``
    (validate everything, then restart every environment: ``seeds[e]`` is environment e's new seed, or ``None`` to
    continue its own generator), ``_restart(rows)`` (the rows of a finished episode, on their own generators),
    ``_advance_rows(actions, restart)`` (step the rows not in the ``restart`` mask, restart those that are: they
    neither move nor score), ``_step_result(restart)`` (rewards, terminated, truncated by the batch's own rules),
    ``_row_steps()`` (steps into each row's episode), ``_observations()`` (the batch's observation rows) and
    ``_info(ended)`` (every row's per-step info in the vector convention, with ``episode_metrics`` on the rows in
    the ``ended`` mask: :func:`vector_convention`); optionally ``_final_info(done)`` (what the rows in ``done``
    report of the episode they finished: by default their ``_info(done)``).

    An environment is ``rows_per_env`` rows (``_build`` sets it: the swarm's robots; 1 elsewhere) that share one
    generator and one episode, so they restart together; ``num_envs`` counts environments and ``self.num_envs``,
    Gymnasium's, rows. Seeding as ``SyncVectorEnv``: ``reset(seed=s)`` seeds environment ``e`` with ``s + e``;
    ``max_episode_steps`` truncates as Gymnasium's ``TimeLimit`` does (also on the step that terminates).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: Rows of one environment (set by ``_build`` where it is more than one).
    rows_per_env = 1

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **kwargs,
    ):
        num_envs, max_episode_steps, autoreset_mode = check_vector_arguments(
            num_envs, max_episode_steps, autoreset_mode
        )
        modes = self.metadata["render_modes"]
        if render_mode not in (None, *modes):
            raise ValueError(
                f"render_mode must be None or one of {modes} for this vector env (gym.make(id) renders all its "
                f"modes), got {show(render_mode)}"
            )
        spaces, render_fps = self._build(num_envs, render_mode, kwargs)
        self.metadata = {**self.metadata, "render_fps": render_fps, "autoreset_mode": autoreset_mode}
        self.autoreset_mode = autoreset_mode
        self.num_envs = num_envs * self.rows_per_env
        self.max_episode_steps = max_episode_steps
        self.render_mode = render_mode
        self.single_observation_space, self.single_action_space = spaces
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        #: No row's episode ended (a reset's info; the restarted rows of a same-step autoreset).
        self._none_ended = read_only(np.zeros(self.num_envs, dtype=bool))
        self._started = False
        self._closed = False

    def _check_open(self) -> None:
        if self._closed:
            raise ClosedEnvironmentError("this vector env is closed")

    def _seeds(self, seed) -> list[int | None]:
        """Environment e's seed for this reset, as ``SyncVectorEnv`` seeds sub-environment e: ``seed + e``, or the
        list's (one per environment, or one per row, of which an environment takes its first row's)."""
        n = self.num_envs // self.rows_per_env
        if seed is None:
            return [None] * n
        if not isinstance(seed, (list, tuple)):
            return [check_int("seed", seed, 0) + e for e in range(n)]
        if len(seed) not in (n, self.num_envs):
            raise ValueError(f"seed must be None, an int or a list of {n} ints/None, got {show(seed)}")
        return [None if s is None else check_int("seed", s, 0) for s in seed[:: len(seed) // n]]

    def reset(self, *, seed=None, options: dict[str, Any] | None = None):
        self._check_open()
        self._reset_rows(self._seeds(seed), options)  # may raise, before anything changes
        self._needs_reset[:] = False
        self._started = True
        return self._observations().copy(), self._info(self._none_ended)

    def step(self, actions):
        self._check_open()
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        actions = self._check_batch_actions(actions)
        restart = self._needs_reset
        self._advance_rows(actions, restart)
        rewards, terminated, truncated = self._step_result(restart)
        if self.max_episode_steps is not None:  # TimeLimit's rule: also on a step that terminates
            truncated |= self._row_steps() >= self.max_episode_steps
        terminated &= ~restart
        truncated &= ~restart
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP or not done.any():
            self._needs_reset = done
            return self._observations().copy(), rewards, terminated, truncated, self._info(done)
        # Same-step autoreset: keep what the finished rows saw, restart them now, report both.
        final_obs = np.full(self.num_envs, None, dtype=object)
        observations = self._observations()
        for row in np.flatnonzero(done).tolist():
            final_obs[row] = observations[row].copy()
        final_info = self._final_info(done)
        self._restart(np.flatnonzero(done).tolist())
        info = self._info(self._none_ended)
        info["final_obs"], info["_final_obs"] = final_obs, done.copy()
        info["final_info"], info["_final_info"] = final_info, done.copy()
        return self._observations().copy(), rewards, terminated, truncated, info

    def _final_info(self, done: np.ndarray) -> dict[str, Any]:
        return only_rows(self._info(done), done)


class RowsVectorEnv(BatchVectorEnv):
    """``num_envs`` rows of one :class:`RowsEnv` class behind Gymnasium's ``VectorEnv`` API.

    Args:
        num_envs: number of sub-environments (rows).
        max_episode_steps: truncate each row's episode after this many steps (``None``: never).
        render_mode: ``"rgb_array"`` renders sub-environment 0.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (a finished row restarts at the next step, which then only
            resets it) or ``AutoresetMode.SAME_STEP`` (it restarts within the step that finished it; the last
            observation and info are in ``info["final_obs"]`` and ``info["final_info"]``).
        **kwargs: the environment's constructor arguments.

    Observations ``(num_envs, ...)``, rewards, terminated and truncated ``(num_envs,)``; ``info`` holds the single
    env's per-step keys in the vector convention (an array per key, with its ``_key`` mask), and
    ``episode_metrics``, a dict of arrays, on the rows whose episode ended this step, time limit included.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}
    #: The batched-rows class this vector env drives (``TaskEnv.VectorEnv`` is this class bound to ``TaskEnv``).
    env_class: type[RowsEnv]

    def _build(self, num_envs, render_mode, kwargs):
        # The class itself with num_envs rows: the same validation, spaces and kernels as the single env.
        core = self.env_class(num_rows=num_envs, render_mode=render_mode, **kwargs)
        self._core = core
        self.observation_structure = getattr(core, "observation_structure", None)
        return (core.observation_space, core.action_space), core.metadata.get("render_fps", 30)

    def _reset_rows(self, seeds, options) -> None:
        core = self._core
        options = core._check_options(options)
        generators = []
        for row, s in enumerate(seeds):
            current = core._row_generator(row)
            if s is None and current is not None:
                generators.append((copy_generator(current), False))
            else:
                generators.append((seeding.np_random(s)[0], True))
        prepared = [core._prepare_row(row, rng, options, new) for row, (rng, new) in enumerate(generators)]  # may raise
        core._commit_rows(prepared)

    def _restart(self, rows) -> None:
        core = self._core
        core._commit_rows([core._prepare_row(row, core._row_generator(row), {}, False) for row in rows])

    def _check_batch_actions(self, actions):
        return self._core._check_actions(actions)

    def _advance_rows(self, actions, restart) -> None:
        core = self._core
        core._actions[:] = actions
        if restart.any():
            self._restart(np.flatnonzero(restart).tolist())
            core._actions[restart] = NO_ACTION  # these rows start a new episode: they neither move nor score
        core._advance(core._actions)
        if not restart[0]:
            core._on_row0_step()

    def _step_result(self, restart):
        core = self._core
        out = core._out
        return out[:, core._reward_column].copy(), out[:, core._terminated_column] > 0.5, core.budget_spent()

    def _row_steps(self) -> np.ndarray:
        return self._core._row_steps()

    def _observations(self) -> np.ndarray:
        return self._core._observations

    def _info(self, ended: np.ndarray) -> dict[str, Any]:
        return self._core._vector_info(ended)

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


RowsEnv.VectorEnv = NativeVector(RowsVectorEnv)


def only_rows(info: dict[str, Any], rows: np.ndarray) -> dict[str, Any]:
    """``info`` (vector convention) for ``rows`` only, as ``SyncVectorEnv`` collects a same-step ``final_info``:
    other rows zero (``None`` in object arrays) and every ``_key`` mask equal to ``rows``."""
    kept: dict[str, Any] = {}
    for key, value in info.items():
        if key.startswith("_"):
            continue
        if isinstance(value, dict):
            kept[key] = only_rows(value, rows)
        else:
            array = np.full(value.shape, None, dtype=object) if value.dtype == object else np.zeros_like(value)
            array[rows] = value[rows]
            kept[key] = array
        kept[f"_{key}"] = rows.copy()
    return kept


def vector_convention(values: dict[str, Any], metrics: dict[str, np.ndarray], ended: np.ndarray) -> dict[str, Any]:
    """A vector env's info in Gymnasium's convention: every row reports every key of ``values`` (each ``_key`` mask
    one shared read-only all-true array), and ``info["episode_metrics"]`` holds ``metrics`` (name -> per-row array)
    for the rows in the ``ended`` mask only (zero elsewhere, each mask equal to ``ended``), as ``SyncVectorEnv``
    gathers the infos of envs that report them on their last step; no ``episode_metrics`` key where no row ended."""
    every_row = np.ones(ended.shape[0], dtype=bool)
    every_row.flags.writeable = False
    info: dict[str, Any] = {}
    for key, value in values.items():
        info[key] = value
        info[f"_{key}"] = every_row
    if ended.any():
        info["episode_metrics"] = only_rows(metrics, ended)
        info["_episode_metrics"] = ended.copy()
    return info
