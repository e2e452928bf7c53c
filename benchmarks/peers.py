"""The peer environments of the performance spec as benchmark cases, with adapters for the non-Gymnasium ones.

CartPole-v1 (``gym.make`` and its native vector env) and MiniGrid are the peers our targets are stated against;
Ant-v5, mpe2 simple_spread and VMAS navigation are the peers of families still to come. A peer whose package is not
installed is listed with a note (and the install command), never silently dropped.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable
from typing import Any

import gymnasium as gym

from benchmarks.harness import Case, Measurement, env_case

__all__ = [
    "ANT",
    "CARTPOLE",
    "MINIGRID",
    "MPE2_SPREAD",
    "SETTING_MAKE",
    "SETTING_VECTOR",
    "VECTOR_NUM_ENVS",
    "VMAS_NAVIGATION",
    "peer_cases",
]

VECTOR_NUM_ENVS = 1024
SETTING_MAKE = "`gym.make` (default wrappers)"
SETTING_VECTOR = f"native vector env, {VECTOR_NUM_ENVS} envs (env-steps/s)"

CARTPOLE = "CartPole-v1"
MINIGRID = "MiniGrid-Empty-8x8-v0"
ANT = "Ant-v5"
MPE2_SPREAD = "mpe2 simple_spread_v3"
VMAS_NAVIGATION = "VMAS navigation"

_VMAS_AGENTS = 4


def peer_cases(*, min_seconds: float, seed: int = 0) -> list[Case]:
    """The peers in the order they should be timed: CartPole, its vector env and MiniGrid first, then the others."""
    kw: dict[str, Any] = {"min_seconds": min_seconds, "seed": seed}
    cases = [
        env_case(CARTPOLE, SETTING_MAKE, lambda: gym.make(CARTPOLE), **kw),
        env_case(
            CARTPOLE,
            SETTING_VECTOR,
            lambda: gym.make_vec(CARTPOLE, num_envs=VECTOR_NUM_ENVS, vectorization_mode="vector_entry_point"),
            vector=True,
            **kw,
        ),
        _if_installed("minigrid", "minigrid", env_case(MINIGRID, SETTING_MAKE, lambda: gym.make(MINIGRID), **kw)),
        _if_installed(
            "mujoco",
            '"gymnasium[mujoco]"',
            env_case(ANT, "`gym.make`, frame_skip 5", lambda: gym.make(ANT), **kw),
        ),
    ]
    for n_agents in (3, 20):
        case = dataclasses.replace(
            env_case(MPE2_SPREAD, f"N = {n_agents}, joint steps/s", _make_mpe2_spread(n_agents), **kw),
            describe=_agent_steps_note(n_agents),
        )
        cases.append(_if_installed("mpe2", "mpe2", case))
    vmas_setting = f"{VECTOR_NUM_ENVS} envs x {_VMAS_AGENTS} agents, 1 torch thread (env-steps/s)"
    cases.append(
        _if_installed("vmas", "vmas", env_case(VMAS_NAVIGATION, vmas_setting, _make_vmas_navigation, vector=True, **kw))
    )
    return cases


def _if_installed(module: str, pip_name: str, case: Case) -> Case:
    """``case``, or the same row marked skipped when ``module`` does not import."""
    try:
        importlib.import_module(module)
    except ImportError:
        case.skip = f"skipped: {module} not installed (pip install {pip_name})"
    return case


def _agent_steps_note(n_agents: int) -> Callable[[Measurement], str]:
    return lambda row: f"{row.steps_per_second * n_agents:,.0f} agent-steps/s"


# ---------------------------------------------------------------------------------------------------- adapters


class _ParallelEnvAsGym:
    """A PettingZoo parallel env seen as one Gymnasium-style env whose step is a joint step of all agents."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.action_space = gym.spaces.Dict({agent: env.action_space(agent) for agent in env.possible_agents})

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        return self.env.reset(seed=seed, options=options)

    def step(self, actions: dict):
        live = self.env.agents
        if len(live) != len(actions):
            actions = {agent: actions[agent] for agent in live}
        obs, rewards, terminations, _, infos = self.env.step(actions)
        # The episode is over once no agent is left, which is when PettingZoo expects a reset.
        done = not self.env.agents
        terminated = any(terminations.values())
        return obs, rewards, done and terminated, done and not terminated, infos

    def close(self) -> None:
        self.env.close()


class _VmasActions:
    """Random batched actions for every VMAS agent, with the Gymnasium ``seed``/``sample`` interface."""

    def __init__(self, env: Any) -> None:
        self.env = env

    def seed(self, seed: int | None = None) -> None:
        import torch

        if seed is not None:
            torch.manual_seed(seed)

    def sample(self) -> list:
        return [self.env.get_random_action(agent) for agent in self.env.agents]


class _VmasBatch:
    """A VMAS environment stepped as a batch, resetting finished sub-environments itself like a VectorEnv."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.num_envs = env.num_envs
        self.action_space = _VmasActions(env)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.env.seed(seed)
        return self.env.reset(), {}

    def step(self, actions: list):
        obs, rewards, dones, infos = self.env.step(actions)
        if dones.all():
            self.env.reset()
        elif dones.any():
            for index in dones.nonzero().flatten().tolist():
                self.env.reset_at(index)
        return obs, rewards, dones, dones, infos

    def close(self) -> None:
        pass


def _make_mpe2_spread(n_agents: int) -> Callable[[], Any]:
    def make() -> Any:
        from mpe2 import simple_spread_v3

        return _ParallelEnvAsGym(simple_spread_v3.parallel_env(N=n_agents))

    return make


def _make_vmas_navigation() -> Any:
    import torch
    import vmas

    # The spec measures VMAS with one torch thread: two threads run 10-100x slower on these 2-core machines.
    torch.set_num_threads(1)
    env = vmas.make_env(
        scenario="navigation",
        num_envs=VECTOR_NUM_ENVS,
        device="cpu",
        continuous_actions=True,
        n_agents=_VMAS_AGENTS,
        seed=0,
    )
    return _VmasBatch(env)
