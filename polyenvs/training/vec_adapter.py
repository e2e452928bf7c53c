"""A Stable-Baselines3 ``VecEnv`` over a native Gymnasium vector env, and the choice between it and ``DummyVecEnv``.

SB3 and Gymnasium's vector API differ in three conventions, which :class:`NativeVecEnvAdapter` translates:

- *Autoreset.* SB3 restarts a finished sub-environment within the step that finished it and returns the new
  episode's first observation, with the last one in ``infos[i]["terminal_observation"]``. That is Gymnasium's
  ``AutoresetMode.SAME_STEP``, whose ``info["final_obs"]`` / ``info["final_info"]`` carry the finished episode; the
  adapter requires a vector env built in that mode (the Buckybot native vector envs support it).
- *Done.* SB3 has one ``dones = terminated | truncated`` and ``infos[i]["TimeLimit.truncated"]`` (truncated and not
  terminated), which on-policy algorithms use to bootstrap the value of a time-limited episode.
- *Info.* SB3 wants a list of per-sub-environment dicts; Gymnasium gives one dict of arrays with ``_key`` masks.
  On a row that finished, the adapter gives the finished episode's whole last info (as ``DummyVecEnv`` does), its
  ``"episode_metrics"`` (which the native env reports on the rows whose episode ended, time limit included) as a
  dict of plain floats, its arrays copied (a native env's ground truth is a view, valid until the next step); on
  other rows only ``"TimeLimit.truncated"`` and the keys named
  in ``info_keys`` (converting every key for every row at every step would cost more than the step itself).

Seeding follows ``DummyVecEnv``: after ``seed(s)`` the next ``reset()`` seeds sub-environment ``i`` with ``s + i``;
since the native vector envs reproduce ``gym.make(id)`` seeded ``s + i`` bit for bit, the adapter gives what
``DummyVecEnv([lambda: gym.make(id)] * n)`` gives: the same observations, rewards (float32), dones and terminal
observations (``tests/test_training_adapter.py``).

A PettingZoo parallel environment (a module path such as ``polyenvs.swarm.corridor_v0``) trains with parameter
sharing through :class:`ParallelVecEnvAdapter`: ``n_envs`` copies, each robot a slot of one SB3 ``VecEnv``
(``n_envs x n_robots`` slots, one policy). SuperSuit's ``pettingzoo_env_to_vec_env_v1`` + ``concat_vec_envs_v1`` do
the same, but with SB3 2.9 they cannot be seeded (``PPO(seed=...)`` fails: its ``ConcatVecEnv`` has no ``seed``,
and its SB3 wrapper's ``reset`` drops the seed), so training would not be reproducible.

``get_attr``/``env_method``/``set_attr`` act on the one native env, which holds every sub-environment: an attribute
is shared by all of them (``get_attr`` returns it once per index), except ``action_masks``, which
``env_method("action_masks")`` (sb3-contrib's ``get_action_masks``) answers per sub-environment from the last
step's ``info["action_mask"]`` as bool arrays.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices

from polyenvs.core.episode_metrics import RecordEpisodeMetrics
from polyenvs.errors import InputError
from polyenvs.evaluation.episodes import EnvTarget, resolve_env
from polyenvs.registry import bare_id

__all__ = [
    "NativeVecEnvAdapter",
    "make_native_vector_env",
    "ParallelVecEnvAdapter",
    "make_training_vec_env",
]

#: The name sb3-contrib's MaskablePPO calls through ``env_method``.
ACTION_MASKS = "action_masks"


def _row_value(value: Any) -> Any:
    """One row's entry of a vector-convention array as the single env would give it: numpy scalars as Python
    numbers, arrays copied (not views of the batch)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.copy()
    return value


def info_row(info: dict[str, Any], row: int, keys: Iterable[str] | None = None) -> dict[str, Any]:
    """Row ``row`` of a Gymnasium vector-convention info dict (arrays with ``_key`` masks; nested dicts too).

    Only keys whose mask is set for the row are kept; ``keys`` limits the top level to those names.
    """
    out: dict[str, Any] = {}
    for key in info if keys is None else keys:
        if key.startswith("_") or key not in info:
            continue
        mask = info.get(f"_{key}")
        if mask is not None and not mask[row]:
            continue
        value = info[key]
        if isinstance(value, dict):
            out[key] = info_row(value, row)
        else:
            out[key] = _row_value(value[row])
    return out


class NativeVecEnvAdapter(VecEnv):
    """An SB3 ``VecEnv`` over a Gymnasium ``VectorEnv`` built with ``autoreset_mode=AutoresetMode.SAME_STEP``.

    Args:
        venv: the Gymnasium vector env (for example ``make_native_vector_env(id, n)``); the adapter owns it and
            closes it.
        info_keys: info keys to give on every row at every step (default: none; a row that finished an episode
            always gets the finished episode's whole info). ``"all"`` gives every key, as ``DummyVecEnv`` does.
    """

    def __init__(self, venv: gym.vector.VectorEnv, info_keys: Sequence[str] | str = ()):
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"NativeVecEnvAdapter needs a vector env in AutoresetMode.SAME_STEP (SB3's convention), got {mode!r}"
            )
        self.venv = venv
        self._all_info = info_keys == "all"
        self._info_keys: tuple[str, ...] = () if self._all_info else tuple(info_keys)
        self._actions: np.ndarray | None = None
        self._last_info: dict[str, Any] | None = None
        self._has_masks = self._env_has_action_masks(venv)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.metadata = {**self.metadata, "autoreset_mode": mode}

    @staticmethod
    def _env_has_action_masks(venv: gym.vector.VectorEnv) -> bool:
        """Whether the single env of this id offers ``action_masks()`` (then its info carries ``action_mask``)."""
        spec = getattr(venv.unwrapped, "spec", None)
        entry_point = getattr(spec, "entry_point", None)
        if entry_point is None:
            return False
        try:
            creator = (
                gym.envs.registration.load_env_creator(entry_point) if isinstance(entry_point, str) else entry_point
            )
        except (ImportError, AttributeError, gym.error.Error):  # pragma: no cover - a broken registration
            return False
        return callable(getattr(creator, ACTION_MASKS, None))

    # ------------------------------------------------------------------------------------------- stepping
    def reset(self):
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = [o for o in self._options if o]
        if options and (len(options) != self.num_envs or any(o != options[0] for o in options)):
            raise NotImplementedError("the native vector env takes one set of reset options for every sub-env")
        obs, info = self.venv.reset(seed=seeds, options=options[0] if options else None)
        self._reset_seeds()
        self._reset_options()
        self._last_info = info
        self.reset_infos = [info_row(info, i) for i in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        obs, rewards, terminated, truncated, info = self.venv.step(actions)
        self._last_info = info
        terminated = np.asarray(terminated, dtype=bool)
        truncated = np.asarray(truncated, dtype=bool)
        dones = terminated | truncated
        time_limit = (truncated & ~terminated).tolist()
        keys = info.keys() if self._all_info else self._info_keys
        if keys:
            infos = [info_row(info, i, keys) for i in range(self.num_envs)]
            for row, flag in zip(infos, time_limit, strict=True):
                row["TimeLimit.truncated"] = flag
        else:
            infos = [{"TimeLimit.truncated": flag} for flag in time_limit]
        if dones.any():
            final_obs, final_info = info["final_obs"], info.get("final_info", {})
            for i in np.flatnonzero(dones).tolist():
                row = info_row(final_info, i)
                row["TimeLimit.truncated"] = time_limit[i]
                row["terminal_observation"] = final_obs[i]
                infos[i] = row
                self.reset_infos[i] = info_row(info, i, (k for k in info if not k.startswith(("final_", "_final_"))))
        return obs, np.asarray(rewards, dtype=np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    # ------------------------------------------------------------------------------- attributes and methods
    def _action_mask(self, row: int) -> np.ndarray:
        if self._last_info is None:
            raise RuntimeError("call reset() before asking for action masks")
        return np.asarray(self._last_info["action_mask"][row], dtype=bool)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        rows = list(self._get_indices(indices))
        if attr_name == ACTION_MASKS:
            if not self._has_masks:
                raise AttributeError(f"{self.venv.unwrapped!r} has no action masks")
            return [functools.partial(self._action_mask, row) for row in rows]
        value = getattr(self.venv, attr_name)  # AttributeError if absent, as SB3's has_attr expects
        return [value for _ in rows]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Sets the attribute on the one native env: every sub-environment shares it."""
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """``action_masks``: one bool mask per sub-environment. Any other method is the native env's, called once
        (it acts on every sub-environment) with its result given once per index."""
        rows = list(self._get_indices(indices))
        if method_name == ACTION_MASKS:
            return [method() for method in self.get_attr(ACTION_MASKS, rows)]
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in rows]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """The native env renders sub-environment 0 only."""
        return [self.venv.render()]


# ------------------------------------------------------------------------------------------------- builders


def make_native_vector_env(env_id: str, num_envs: int, env_kwargs: dict | None = None) -> gym.vector.VectorEnv:
    """``gym.make_vec`` of the id's native vector env in same-step autoreset mode (max_episode_steps from the spec
    unless ``env_kwargs`` sets it)."""
    import polyenvs  # noqa: F401

    return gym.make_vec(
        bare_id(env_id),
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
        **dict(env_kwargs or {}),
    )


def _native_same_step(env_id: str, n_envs: int, env_kwargs: dict, required: bool) -> gym.vector.VectorEnv | None:
    """The native vector env in same-step mode; None where it has no such mode (unless ``required``)."""
    try:
        venv = make_native_vector_env(env_id, n_envs, env_kwargs)
    except TypeError as exc:
        if "autoreset_mode" not in str(exc):
            raise
        if required:  # a vector env without Gymnasium's autoreset_mode argument
            raise InputError(f"the native vector env of {env_id} has no same-step autoreset mode") from None
        return None
    if venv.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
        venv.close()
        if required:
            raise InputError(f"the native vector env of {env_id} has no same-step autoreset mode")
        return None
    return venv


def make_training_vec_env(
    env: str | EnvTarget,
    n_envs: int = 1,
    *,
    seed: int | None = None,
    env_kwargs: dict | None = None,
    wrappers: Sequence[Callable[[gym.Env], gym.Env]] = (),
    vec_env: str = "auto",
) -> VecEnv:
    """The SB3 ``VecEnv`` that training uses, with per-episode returns and lengths in ``infos[i]["episode"]``.

    ``env``: an id or module path with its ``env_kwargs``, or an :class:`~polyenvs.evaluation.episodes.EnvTarget` resolved
    already (``polyenvs train`` resolves the name once; ``env_kwargs`` are then the target's). ``vec_env``:
    ``"native"`` (:class:`NativeVecEnvAdapter` under ``VecMonitor``), ``"dummy"`` (SB3's ``make_vec_env``:
    ``DummyVecEnv`` of ``Monitor(gym.make(id))`` with the episode's metrics on its time-limit truncations, then
    ``wrappers``; a PettingZoo environment's copies are wrapped
    by ``wrappers``, which must then be parallel-env wrappers), or ``"auto"``: native where the id has a
    native vector env and no per-env ``wrappers`` are asked for (a ``gym.Wrapper`` wraps one env, and the native env
    is all of them at once) and its native env has Gymnasium's same-step autoreset mode. After ``seed``, the first
    reset seeds sub-env ``i`` with ``seed + i``. Bad ``env_kwargs`` raise :class:`~polyenvs.errors.InputError`.
    """
    target = env if isinstance(env, EnvTarget) else resolve_env(env, env_kwargs)
    if target.parallel:
        venv = _parallel_vec_env(target, n_envs, wrappers, vec_env)
    else:
        venv = _gymnasium_vec_env(target, n_envs, wrappers, vec_env)
    if seed is not None:
        venv.seed(seed)
    return venv


def _parallel_vec_env(target: EnvTarget, n_envs: int, wrappers: Sequence[Callable], vec_env: str) -> VecEnv:
    """``n_envs`` copies of a PettingZoo swarm, each wrapped by ``wrappers``, as one VecEnv of their robots."""
    from polyenvs.evaluation.episodes import make_env

    if vec_env == "native":
        raise InputError(
            f"{target.env_id} is a PettingZoo environment: it trains on its robots, not a native vector env"
        )
    return ParallelVecEnvAdapter(
        [_wrapped(make_env(target.env_id, target.env_kwargs), wrappers) for _ in range(n_envs)]
    )


def _gymnasium_vec_env(target: EnvTarget, n_envs: int, wrappers: Sequence[Callable], vec_env: str) -> VecEnv:
    """A Gymnasium id's training VecEnv: its native vector env where ``vec_env`` asks for one and it can be had,
    else SB3's ``DummyVecEnv`` of ``gym.make`` copies (see :func:`make_training_vec_env`)."""
    if vec_env not in ("auto", "native", "dummy"):
        raise InputError(f"vec_env must be 'auto', 'native' or 'dummy', got {vec_env!r}")
    if vec_env == "native" and wrappers:
        raise InputError("per-env wrappers (env_wrapper) need vec_env='dummy': the native env is every env at once")
    env_id, env_kwargs = target.env_id, dict(target.env_kwargs or {})
    venv: VecEnv | None = None
    try:
        if vec_env == "native" or (vec_env == "auto" and target.native_vector and not wrappers):
            if not target.native_vector:
                raise InputError(f"{env_id} has no native vector env (no vector_entry_point)")
            native = _native_same_step(env_id, n_envs, env_kwargs, required=vec_env == "native")
            if native is not None:
                venv = VecMonitor(NativeVecEnvAdapter(native))
        if venv is None:
            venv = _dummy_vec_env(env_id, n_envs, env_kwargs, wrappers)
    except (TypeError, ValueError, gym.error.Error) as exc:
        if isinstance(exc, InputError) or not env_kwargs:
            raise
        raise InputError(f"bad environment keyword arguments for {env_id}: {exc}") from exc
    return venv


def _dummy_vec_env(env_id: str, n_envs: int, env_kwargs: dict, wrappers: Sequence[Callable]) -> VecEnv:
    """SB3's ``make_vec_env``: ``DummyVecEnv`` of ``Monitor(gym.make(id))``, each wrapped by
    :func:`_with_episode_metrics`, then by ``wrappers``."""
    from stable_baselines3.common.env_util import make_vec_env

    wrapper_class = functools.partial(_wrapped, wrappers=(_with_episode_metrics, *wrappers))
    return make_vec_env(
        env_id, n_envs=n_envs, env_kwargs=env_kwargs, vec_env_cls=DummyVecEnv, wrapper_class=wrapper_class
    )


def _with_episode_metrics(env: gym.Env) -> gym.Env:
    """``env`` under :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` where it reports metrics (a
    ``TimeLimit`` truncation's info then has them, as the native env's has); another Gymnasium id's env as it is."""
    return RecordEpisodeMetrics(env) if callable(getattr(env.unwrapped, "episode_metrics", None)) else env


def _wrapped(env, wrappers: Sequence[Callable]):
    for wrap in wrappers:
        env = wrap(env)
    return env


class ParallelVecEnvAdapter(VecEnv):
    """PettingZoo parallel environments as one SB3 ``VecEnv`` whose sub-environments are their robots.

    Slot ``k * n_robots + j`` is robot ``possible_agents[j]`` of copy ``k``. A robot that leaves the episode gets
    ``done`` with its ``terminal_observation``, its ``episode`` (return, length, seconds: what ``VecMonitor`` would
    give, for real robots only) and its ``episode_metrics``; until every robot of its copy has left, its slot sees
    zeros, reward 0 and actions that are ignored (SuperSuit's "black death"), and when the copy restarts such
    slots end that filler with ``done`` but no ``episode``. After ``seed(s)`` the next ``reset()`` seeds copy ``k``
    with ``s + k``. ``TimeLimit.truncated`` is set for a robot truncated and not terminated.
    """

    def __init__(self, envs: list):
        from polyenvs.evaluation.rollout import agent_spaces

        self.envs = list(envs)
        self.robots = list(self.envs[0].possible_agents)
        self.slot_of = {name: j for j, name in enumerate(self.robots)}
        observation_space, action_space = agent_spaces(self.envs[0])
        super().__init__(len(self.envs) * len(self.robots), observation_space, action_space)
        self._observations = np.zeros((self.num_envs, *observation_space.shape), dtype=observation_space.dtype)
        self._filler = np.zeros(self.num_envs, dtype=bool)  # slots whose robot has left
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._actions: np.ndarray | None = None
        self._start = time.monotonic()

    def _reset_copy(self, k: int, seed: int | None) -> None:
        n = len(self.robots)
        observations, infos = self.envs[k].reset(seed=seed, options=self._options[k] or None)
        block = slice(k * n, (k + 1) * n)
        self._observations[block] = 0
        self._filler[block] = True
        for name, obs in observations.items():
            i = k * n + self.slot_of[name]
            self._observations[i] = obs
            self._filler[i] = False
            self.reset_infos[i] = infos.get(name, {})
        self._returns[block] = 0.0
        self._lengths[block] = 0

    def reset(self) -> np.ndarray:
        self.reset_infos = [{} for _ in range(self.num_envs)]
        for k in range(len(self.envs)):
            self._reset_copy(k, self._seeds[k])
        self._reset_seeds()
        self._reset_options()
        return self._observations.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        n = len(self.robots)
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict] = [{} for _ in range(self.num_envs)]
        for k, env in enumerate(self.envs):
            live = list(env.agents)
            base = k * n
            observations, step_rewards, terminations, truncations, step_infos = env.step(
                {name: self._actions[base + self.slot_of[name]] for name in live}
            )
            for name in live:
                i = base + self.slot_of[name]
                rewards[i] = step_rewards[name]
                self._returns[i] += float(step_rewards[name])
                self._lengths[i] += 1
                if name in observations:
                    self._observations[i] = observations[name]
                if terminations[name] or truncations[name]:
                    info = dict(step_infos.get(name, {}))
                    info["terminal_observation"] = self._observations[i].copy()
                    info["TimeLimit.truncated"] = bool(truncations[name] and not terminations[name])
                    info["episode"] = {
                        "r": float(self._returns[i]),
                        "l": int(self._lengths[i]),
                        "t": round(time.monotonic() - self._start, 6),
                    }
                    infos[i] = info
                    dones[i] = True
                    self._observations[i] = 0
                    self._filler[i] = True
            if not env.agents:
                block = slice(base, base + n)
                ended_earlier = self._filler[block] & ~dones[block]
                for j in np.flatnonzero(ended_earlier):
                    infos[base + j] = {"terminal_observation": np.zeros_like(self._observations[base + j])}
                dones[block] = True
                self._reset_copy(k, None)
                for j in range(n):
                    infos[base + j]["reset_info"] = self.reset_infos[base + j]
        return self._observations.copy(), rewards, dones, infos

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def seed(self, seed: int | None = None):
        self._seeds = [None if seed is None else seed + k for k in range(len(self.envs))]
        return self._seeds

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.envs[i // len(self.robots)], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for k in {i // len(self.robots) for i in self._get_indices(indices)}:
            setattr(self.envs[k], attr_name, value)

    def env_method(self, method_name: str, *args, indices: VecEnvIndices = None, **kwargs) -> list[Any]:
        return [
            getattr(self.envs[i // len(self.robots)], method_name)(*args, **kwargs) for i in self._get_indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> list[np.ndarray]:
        return [env.render() for env in self.envs]
