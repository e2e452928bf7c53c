"""One rollout per kind of environment, behind ``evaluate``, ``leaderboard`` and ``record``.

A command names an environment by a Gymnasium id (``"polyenvs/BuckybotGoal-v0"``, or any id Gymnasium knows) or by
a PettingZoo module path (``"polyenvs.swarm.corridor_v0"``, or any importable module with a ``parallel_env``
function); :func:`make_env` builds either, and the functions below take whichever they are given:

- :func:`agent_spaces`: the spaces a policy sees, one agent's. Robots of a parallel environment share one policy
  (parameter sharing, as SuperSuit and VMAS train them), built from the first agent's spaces.
- :func:`run_episode`: one seeded episode, ``{"seed", "return", "length", "metrics"}``; ``metrics`` are the
  environment's at the episode's end, ``env.unwrapped.episode_metrics()`` where it has one (every polyenvs env: a
  truncation by Gymnasium's ``TimeLimit`` leaves them out of the last ``info``), else the last
  ``info["episode_metrics"]``. For a parallel environment
  the policy's ``predict`` gets the live robots' observations as one batch (first axis = robots), ``return`` is
  the mean over robots of each robot's summed reward, ``length`` counts cycles, and ``metrics`` are the
  environment's own whole-episode metrics (``env.unwrapped.episode_metrics()``, where it has one: totals, minima
  and fractions over the swarm), else the mean over robots of the ``info["episode_metrics"]`` each robot reports
  when it leaves the episode.
- :func:`episode_frames`: the ``rgb_array`` frames of one seeded episode (``polyenvs record``).

Conventions a parallel environment keeps to plug in (the shared suite ``tests/test_parallel_shared.py`` checks
them): ``parallel_env(max_cycles=..., render_mode=..., **kwargs)`` raises ``ValueError`` naming a bad keyword;
all robots share one observation and one action space; a robot's last ``info`` holds its ``episode_metrics``;
a robot that left gets no observation and ``step({})`` with no robot left returns empty dicts.
"""

from __future__ import annotations

import difflib
import functools
import importlib
import inspect
from typing import Any

import gymnasium as gym
import numpy as np
from pettingzoo import ParallelEnv

from polyenvs.registry import PARALLEL_ENV_IDS, bare_id, entry

__all__ = [
    "SharedPolicy",
    "UnknownEnvironment",
    "agent_spaces",
    "env_kind",
    "episode_frames",
    "final_metrics",
    "is_parallel",
    "make_env",
    "policy_action",
    "run_episode",
    "takes_action_masks",
    "unknown_id_help",
]


class UnknownEnvironment(LookupError):
    """Neither a Gymnasium id nor an importable module with ``parallel_env``."""


def is_parallel(env) -> bool:
    """Whether ``env`` is a PettingZoo parallel environment (else a Gymnasium one)."""
    return isinstance(env, ParallelEnv)


def _parallel_module(name: str):
    """The module ``name`` if it is a PettingZoo parallel environment's module, else ``None``."""
    if "/" in name or not name.replace("_", "").replace(".", "").isalnum():
        return None
    try:
        module = importlib.import_module(name)
    except ImportError:
        return None
    return module if callable(getattr(module, "parallel_env", None)) else None


def unknown_id_help(env_id: str) -> str:
    """What to tell a user who named ``env_id``, which is neither a Gymnasium id nor a PettingZoo module: the nearest
    of our PettingZoo modules (a name without a namespace, close to one), else Gymnasium's own help (the near name in
    the namespace, the versions that exist); ``""`` when neither has any (a malformed name, or an id that exists)."""
    name = bare_id(env_id)
    if "/" not in name:
        by_name = {**{m.rsplit(".", 1)[-1]: m for m in PARALLEL_ENV_IDS}, **{m: m for m in PARALLEL_ENV_IDS}}
        near = difflib.get_close_matches(name, by_name, n=1)
        if near:
            return f"Did you mean: `{by_name[near[0]]}`?"
    try:
        gym.spec(name)
    except (gym.error.UnregisteredEnv, gym.error.DeprecatedEnv) as exc:
        return str(exc)
    except gym.error.Error:  # malformed, or a version-less name
        pass
    return ""


def env_kind(env_id: str) -> str:
    """``"gymnasium"`` for a registered Gymnasium id, ``"pettingzoo"`` for a module with ``parallel_env``;
    :class:`UnknownEnvironment` for anything else (nothing is built)."""
    import polyenvs  # noqa: F401  (registers the ids)

    env_id = bare_id(env_id)
    if env_id in gym.registry:
        return "gymnasium"
    if _parallel_module(env_id) is None:
        raise UnknownEnvironment(env_id)
    return "pettingzoo"


def make_env(env_id: str, env_kwargs: dict | None = None, **extra):
    """Build ``env_id`` with the user's ``env_kwargs`` and the caller's ``extra`` (``render_mode``).

    A Gymnasium id goes through ``gym.make``; a module path through its ``parallel_env``, with the registry row's
    ``kwargs`` under the caller's keywords (its episode limit is the module's default, ``MAX_CYCLES``). Raises
    :class:`UnknownEnvironment` for a name that is neither; the environment's own errors (``TypeError``,
    ``ValueError``, ``gym.error.Error``) propagate.
    """
    env_id = bare_id(env_id)
    kwargs = {**dict(env_kwargs or {}), **extra}
    if env_kind(env_id) == "gymnasium":
        return gym.make(env_id, **kwargs)
    module = _parallel_module(env_id)
    try:
        row_kwargs = entry(env_id).kwargs
    except KeyError:  # a user's own module: its own defaults
        row_kwargs = {}
    return module.parallel_env(**{**row_kwargs, **kwargs})


def agent_spaces(env) -> tuple[gym.Space, gym.Space]:
    """``(observation_space, action_space)`` of the policy that acts for ``env`` (one robot's, if parallel)."""
    if is_parallel(env):
        first = env.possible_agents[0]
        return env.observation_space(first), env.action_space(first)
    return env.observation_space, env.action_space


@functools.lru_cache(maxsize=256)
def _signature_takes_action_masks(function) -> bool:
    try:
        return "action_masks" in inspect.signature(function).parameters
    except (TypeError, ValueError):  # builtins without a signature
        return False


def takes_action_masks(agent) -> bool:
    """Whether ``agent.predict`` takes ``action_masks`` (MaskablePPO models and the trained-policy wrapper)."""
    predict = agent.predict
    function = getattr(predict, "__func__", None)  # a method: look its function up once, not at every step
    if function is None:
        return _signature_takes_action_masks.__wrapped__(predict)
    return _signature_takes_action_masks(function)


def policy_action(agent, obs, state, episode_start, info: dict, deterministic: bool = True):
    """``agent.predict`` for one step of one Gymnasium env: ``(action, state)``.

    ``info["action_mask"]`` goes to policies whose ``predict`` takes ``action_masks`` (MaskablePPO and the trained
    policy wrapper); the hand baselines never see it (they act on the observation alone).
    """
    kwargs = {}
    if "action_mask" in info and takes_action_masks(agent):
        kwargs["action_masks"] = np.asarray(info["action_mask"]).astype(bool)
    return agent.predict(
        obs, state=state, episode_start=np.atleast_1d(episode_start), deterministic=deterministic, **kwargs
    )


def run_episode(env, agent, seed: int) -> dict[str, Any]:
    """One episode seeded ``seed``: ``{"seed", "return", "length", "metrics"}`` (see the module docstring)."""
    if is_parallel(env):
        return _run_parallel_episode(env, agent, seed)
    obs, info = env.reset(seed=seed)
    state, start, total, length = None, True, 0.0, 0
    while True:
        action, state = policy_action(agent, obs, state, start, info)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        length += 1
        start = False
        if terminated or truncated:
            break
    return {"seed": seed, "return": total, "length": length, "metrics": final_metrics(env, info)}


def final_metrics(env: gym.Env, info: dict) -> dict[str, float]:
    """The metrics of the episode ``env`` just ended with ``info``: its ``env.unwrapped.episode_metrics()`` where it
    has one (a ``TimeLimit`` truncation's info lacks them), else ``info["episode_metrics"]`` (empty if none)."""
    method = getattr(env.unwrapped, "episode_metrics", None)
    metrics = method() if callable(method) else info.get("episode_metrics", {})
    return {k: float(v) for k, v in metrics.items()}


class SharedPolicy:
    """One policy acting for every robot of a parallel environment: the live robots' observations as one batch,
    with each robot's recurrent state (hand baselines' memory) kept in its own row across steps."""

    def __init__(self, env: ParallelEnv, agent):
        self.agent = agent
        self.row = {name: i for i, name in enumerate(env.possible_agents)}
        self.state: np.ndarray | None = None
        self.started: set[str] = set()

    def act(self, observations: dict, infos: dict) -> dict:
        live = list(observations)
        rows = np.fromiter((self.row[a] for a in live), dtype=np.int64, count=len(live))
        batch = np.stack([np.asarray(observations[a]) for a in live])
        episode_start = np.array([a not in self.started for a in live])
        self.started.update(live)
        state = self.state[rows] if self.state is not None else None
        kwargs = {}
        if live and all("action_mask" in infos.get(a, {}) for a in live) and takes_action_masks(self.agent):
            kwargs["action_masks"] = np.stack([np.asarray(infos[a]["action_mask"]).astype(bool) for a in live])
        actions, new_state = self.agent.predict(
            batch, state=state, episode_start=episode_start, deterministic=True, **kwargs
        )
        if new_state is not None:
            new_state = np.asarray(new_state)
            if self.state is None:
                self.state = np.zeros((len(self.row), *new_state.shape[1:]), dtype=new_state.dtype)
            self.state[rows] = new_state
        return {a: actions[i] for i, a in enumerate(live)}


def _run_parallel_episode(env: ParallelEnv, agent, seed: int) -> dict[str, Any]:
    observations, infos = env.reset(seed=seed)
    shared = SharedPolicy(env, agent)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    robot_metrics: list[dict] = []
    length = 0
    while env.agents:
        actions = shared.act({a: observations[a] for a in env.agents}, infos)
        observations, rewards, terminations, truncations, infos = env.step(actions)
        length += 1
        for name, reward in rewards.items():
            returns[name] += float(reward)
        for name in actions:
            if terminations.get(name, False) or truncations.get(name, False):
                robot_metrics.append(infos.get(name, {}).get("episode_metrics", {}))
    swarm_metrics = getattr(env.unwrapped, "episode_metrics", None)
    if callable(swarm_metrics):
        metrics = {k: float(v) for k, v in swarm_metrics().items()}
    else:
        names = sorted(set().union(*robot_metrics)) if robot_metrics else []
        metrics = {k: float(np.mean([m[k] for m in robot_metrics if k in m])) for k in names}
    return {"seed": seed, "return": float(np.mean(list(returns.values()))), "length": length, "metrics": metrics}


def episode_frames(env, agent, seed: int, max_steps: int, every: int = 1) -> list[np.ndarray]:
    """The ``rgb_array`` frames of one episode seeded ``seed``, at most ``max_steps`` steps (or cycles) long: the
    first, then one every ``every`` steps (only those are rendered: a long MuJoCo episode at 100 steps per second
    need not draw them all), and the last."""
    if is_parallel(env):
        observations, infos = env.reset(seed=seed)
        shared = SharedPolicy(env, agent)
        frames = [env.render()]
        for step in range(1, max_steps + 1):
            if not env.agents:
                break
            observations, _, _, _, infos = env.step(shared.act({a: observations[a] for a in env.agents}, infos))
            if step % every == 0 or not env.agents:
                frames.append(env.render())
        return frames
    obs, info = env.reset(seed=seed)
    frames, state, start = [env.render()], None, True
    for step in range(1, max_steps + 1):
        action, state = policy_action(agent, obs, state, start, info)
        obs, _, terminated, truncated, info = env.step(action)
        start = False
        if step % every == 0 or terminated or truncated:
            frames.append(env.render())
        if terminated or truncated:
            break
    return frames
