"""The residual policy's environment half: Gymnasium and PettingZoo wrappers whose action corrects a hand
baseline's.

:class:`ResidualPolicy` turns an environment with Box actions into the environment of a residual agent: its action is
a correction of a hand baseline's action (:mod:`baselines.residual`). It works from a plain script::

    env = baselines.residual.ResidualPolicy(gym.make("polyenvs/APLiteCorridor-v0"), baseline="paper", scale=0.5)

and ``polyenvs train ID --residual paper`` trains on it (a ``DummyVecEnv`` of wrapped ``gym.make`` envs: each
sub-environment wraps its own env and its own baseline, so each carries its own memory).

:class:`ParallelResidualPolicy` does the same for every robot of a PettingZoo swarm (one policy for all robots,
parameter sharing, each robot with its own row of the baseline's memory)::

    env = baselines.residual.ParallelResidualPolicy(corridor_v0.parallel_env(), baseline="paper", scale=0.5)
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.error import ResetNeeded
from pettingzoo.utils.wrappers import BaseParallelWrapper

from baselines.residual.compose import ResidualSpec, make_composer
from polyenvs.core.validation import real_array, show

__all__ = ["ParallelResidualPolicy", "ResidualPolicy"]

_START, _GOING = np.array([True]), np.array([False])


class ResidualPolicy(gym.Wrapper):
    """The environment of a residual agent: its action is ``residual``, the environment's is
    ``clip(base + scale x residual, low, high)``, ``base`` the baseline's action for the current observation.

    ## Action Space
    ``Box(-1, 1, env's action shape, float32)``: the correction before ``scale``. A zero action is the baseline's
    action, bit for bit (the combined action keeps the base action's dtype). An action outside [-1, 1], non-finite
    or of the wrong shape raises ``ValueError`` and changes nothing.

    ## Observation Space
    The environment's observation with the base action appended (``observe_base=True``, the default), in the
    observation's dtype and with the action space's bounds; the environment's observation alone otherwise.

    ## Holding a correction
    With ``hold = k`` one step of the wrapper is k steps of the environment with the same correction, the baseline
    run and recombined on each (its own output is never held: the beasts' gait times its trajectory by its calls),
    their rewards summed; it stops early where the episode ends. The agent then decides every k control ticks (50
    ms at k = 5 on a beast) while the environment as registered keeps its own period, and a trained agent loaded
    for evaluation (:mod:`baselines.trained`) holds its correction the same way, so it acts as it trained.

    ## Baseline memory
    The baseline runs inside the wrapper on every observation, its ``state`` carried from step to step and restarted
    (``episode_start=True``) on the observation a reset returns; it runs on an episode's last observation too (to
    append its action), which a stochastic baseline's generator counts. A reset with a seed also reseeds a baseline
    that has a ``seed`` method (the cart's random bounce), so the same seed gives the same episode.

    ## Arguments
    | argument | default | meaning |
    | --- | --- | --- |
    | env | - | a polyenvs environment with Box observations and actions (``gym.make(id)``) |
    | baseline | "paper" | a hand baseline of the id (``polyenvs list``); "paper" is the id's paper algorithm |
    | scale | 0.5 | the correction is ``scale x residual``, in (0, 2] |
    | observe_base | True | append the base action to the observation |
    | env_id | None | the id (default ``env.spec.id``, which ``gym.make`` sets) |
    | hold | 1 | each correction is applied for this many environment steps, 1 to 100 |
    | seed | 0 | seeds a stochastic baseline until a reset gives a seed |

    Every argument is checked at construction (``ValueError`` naming it).
    """

    def __init__(
        self,
        env: gym.Env,
        baseline: str = "paper",
        scale: float = 0.5,
        observe_base: bool = True,
        env_id: str | None = None,
        *,
        seed: int | None = 0,
        hold: int = 1,
    ):
        spec = ResidualSpec(baseline, scale, observe_base, hold)
        env_id = env_id if env_id is not None else getattr(env.spec, "id", None)
        if not isinstance(env_id, str):
            raise ValueError(f"env_id: {show(env)} has no spec id (not made by gym.make); pass env_id")
        composer = make_composer(spec, env_id, env.observation_space, env.action_space, seed=seed)
        super().__init__(env)
        self.composer = composer
        self.action_space = composer.action_space
        self.observation_space = composer.observation_space
        self._base_action: np.ndarray | None = None
        self._state = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        reseed = getattr(self.composer.base, "seed", None)
        if seed is not None and callable(reseed):
            reseed(seed)
        self._base_action, self._state = self.composer.base_action(obs, self._state, _START)
        return self.composer.observe(obs, self._base_action), info

    def step(self, action):
        """``hold`` steps of the environment with this correction (fewer if the episode ends), the baseline
        recombined on each; their rewards summed, the last step's observation, flags and info."""
        if self._base_action is None:
            raise ResetNeeded("call reset() before step()")
        residual = real_array("action", action)
        if residual.shape != self.action_space.shape or not np.all(np.abs(residual) <= 1.0):
            raise ValueError(f"action must be {self.action_space.shape} numbers in [-1, 1], got {show(action)}")
        total = None
        for _ in range(self.composer.spec.hold):
            obs, reward, terminated, truncated, info = self.env.step(self.composer.combine(self._base_action, residual))
            total = reward if total is None else total + reward  # one tick's reward as it is (hold 1: unchanged)
            self._base_action, self._state = self.composer.base_action(obs, self._state, _GOING)
            if terminated or truncated:
                break
        return self.composer.observe(obs, self._base_action), total, terminated, truncated, info


class ParallelResidualPolicy(BaseParallelWrapper):
    """The PettingZoo swarm of residual agents: every robot's action is a correction of the baseline's action for
    that robot, ``clip(base + scale x residual, low, high)``, as :class:`ResidualPolicy` composes it.

    ## Spaces
    Per robot, those of :class:`ResidualPolicy`: the correction ``Box(-1, 1, action shape, float32)``; the robot's
    observation with its base action appended (``observe_base``). A step with a missing, extra or bad correction
    (outside [-1, 1], non-finite, of the wrong shape) raises ``ValueError`` and changes nothing.

    ## Baseline memory
    One baseline for the swarm, each robot with its own row of its memory, restarted on the observations a reset
    returns (a robot's episode restarts only with the swarm's). The baseline acts for the robots still in the
    episode as one batch, in the order of ``env.agents``: exactly the batch a shared policy gets in an evaluation
    (:mod:`polyenvs.evaluation.rollout`), so a zero correction is the baseline's episode bit for bit. A robot that
    leaves gets its base action (appended to its last observation) from a call of its own.

    ## Arguments
    | argument | default | meaning |
    | --- | --- | --- |
    | env | - | a PettingZoo parallel swarm with Box observations and actions |
    | baseline | "paper" | a hand baseline of the swarm's module (``polyenvs list``) |
    | scale | 0.5 | the correction is ``scale x residual``, in (0, 2] |
    | observe_base | True | append the base action to each robot's observation |
    | env_id | None | the module path (default: the module that defines ``env.unwrapped``'s class) |
    | seed | 0 | seeds a stochastic baseline |

    Every argument is checked at construction (``ValueError`` naming it). Corrections are not held here (``hold`` 1):
    a swarm's robots leave at different steps, inside a hold.
    """

    def __init__(self, env, baseline: str = "paper", scale: float = 0.5, observe_base: bool = True,
                 env_id: str | None = None, seed: int | None = 0):  # fmt: skip
        spec = ResidualSpec(baseline, scale, observe_base)
        env_id = env_id if env_id is not None else type(env.unwrapped).__module__
        first = env.possible_agents[0]
        composer = make_composer(spec, env_id, env.observation_space(first), env.action_space(first), seed=seed)
        super().__init__(env)
        self.composer = composer
        self._row = {name: i for i, name in enumerate(env.possible_agents)}
        self._memory: np.ndarray | None = None
        self._base: dict = {}

    def observation_space(self, agent):
        return self.composer.observation_space

    def action_space(self, agent):
        return self.composer.action_space

    def reset(self, seed: int | None = None, options: dict | None = None):
        observations, infos = self.env.reset(seed=seed, options=options)
        self._memory, self._base = None, {}
        return self._observe(observations, start=True), infos

    def step(self, actions: dict):
        if self._memory is None:
            raise ResetNeeded("call reset() before step()")
        if not isinstance(actions, dict) or set(actions) != set(self.env.agents):
            raise ValueError(f"actions must name the robots in the episode, {self.env.agents}, got {show(actions)}")
        combined = {name: self.composer.combine(self._base[name], self._residual(name, actions)) for name in actions}
        observations, rewards, terminations, truncations, infos = self.env.step(combined)
        return self._observe(observations, start=False), rewards, terminations, truncations, infos

    def _residual(self, name, actions: dict) -> np.ndarray:
        residual = real_array("actions", actions[name])
        if residual.shape != self.composer.action_space.shape or not np.all(np.abs(residual) <= 1.0):
            shape = self.composer.action_space.shape
            raise ValueError(f"actions[{name!r}] must be {shape} numbers in [-1, 1], got {show(actions[name])}")
        return residual

    def _observe(self, observations: dict, start: bool) -> dict:
        """Each robot's observation with its base action: the robots still in the episode as one batch, then
        (its own call) those that left on this step."""
        live = [name for name in self.env.agents if name in observations]
        left = [name for name in observations if name not in set(live)]
        self._base = {}
        for names in (live, left):
            if names:
                self._base.update(self._base_actions(names, observations, start))
        return {name: self.composer.observe(observations[name], self._base[name]) for name in observations}

    def _base_actions(self, names: list, observations: dict, start: bool) -> dict:
        rows = [self._row[name] for name in names]
        batch = np.stack([np.asarray(observations[name]) for name in names])
        memory = self._memory[rows] if self._memory is not None else None
        actions, memory = self.composer.base_action(batch, memory, np.full(len(names), start))
        memory = np.asarray(memory, dtype=np.float64).reshape(len(names), -1)
        if self._memory is None:
            self._memory = np.zeros((len(self._row), memory.shape[1]))
        self._memory[rows] = memory
        return dict(zip(names, actions, strict=True))
