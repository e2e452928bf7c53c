"""The one small interface every hand baseline keeps: Stable-Baselines3's ``predict``.

``predict(observation, state=None, episode_start=None, deterministic=True) -> (action, state)`` accepts a single
observation or a batch (first axis = environments), so a baseline works wherever an SB3 model does
(``stable_baselines3.common.evaluation.evaluate_policy``, ``polyenvs evaluate``). A baseline sees only the
observation; memory (the paper's algorithms sometimes need some) travels in ``state``, one row per environment,
and is cleared where ``episode_start`` is true.
"""

from __future__ import annotations

import copy

import numpy as np
from gymnasium import spaces

__all__ = ["Policy", "RandomPolicy"]


class Policy:
    """Base class: subclasses implement ``act(observation, memory) -> action`` for one environment."""

    #: Length of the per-environment memory row (0 for memoryless policies).
    memory_size: int = 0
    #: The constructor parameters a search may tune (``polyenvs tune``): a frozen dataclass of fields declared with
    #: :func:`polyenvs.core.parameters.parameter`, whose defaults are the constructor's (the paper's values) and whose
    #: ranges are the search's (inside what the constructor accepts); None where nothing is tuned.
    tunables: type | None = None

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Space):
        self.observation_space = observation_space
        self.action_space = action_space

    def describe(self) -> dict:
        """Name and parameters, stored with evaluation results."""
        return {"name": type(self).__name__}

    def initial_memory(self) -> np.ndarray:
        return np.zeros(self.memory_size)

    def act(self, observation: np.ndarray, memory: np.ndarray) -> int | np.ndarray:
        raise NotImplementedError

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        single = obs.shape == self.observation_space.shape
        batch = obs[None] if single else obs
        n = batch.shape[0]
        memory = np.array(state, dtype=np.float64) if state is not None else None
        if memory is None or memory.shape != (n, self.memory_size):
            memory = np.tile(self.initial_memory(), (n, 1))
        if episode_start is not None:
            restart = np.asarray(episode_start, dtype=bool)
            # Most steps start nothing: no mask to broadcast and apply (a shape that cannot broadcast still raises).
            if restart.any() or restart.shape not in ((), (1,), (n,)):
                memory[np.broadcast_to(restart, (n,))] = self.initial_memory()
        actions = np.array([self.act(batch[i], memory[i]) for i in range(n)])
        return (actions[0] if single else actions), memory


class RandomPolicy(Policy):
    """Uniformly random actions from the action space, seeded for reproducible evaluations."""

    def __init__(self, observation_space, action_space, seed: int | None = None):
        # A private copy, so seeding it leaves the environment's own action space alone.
        super().__init__(observation_space, copy.deepcopy(action_space))
        self.action_space.seed(seed)
        self._bounds = _bounded_float_box(self.action_space)

    def describe(self):
        return {"name": "random"}

    def act(self, observation, memory):
        if self._bounds is None:
            return self.action_space.sample()
        # Box.sample's draw for a bounded float box without its per-call masks: a uniform over the flattened
        # bounds, cast to the box's dtype; the same generator calls, so the same actions bit for bit.
        low, high = self._bounds
        space = self.action_space
        return space.np_random.uniform(low=low, high=high, size=low.shape).reshape(space.shape).astype(space.dtype)


def _bounded_float_box(space: spaces.Space) -> tuple[np.ndarray, np.ndarray] | None:
    """The flattened bounds ``Box.sample`` draws a bounded float box's uniform between, or None for any other space
    (sampled by the space itself). Its normal and exponential draws for unbounded coordinates are then empty and take
    nothing from the generator (``tests/test_baselines.py`` checks the draws against ``Box.sample``)."""
    if not isinstance(space, spaces.Box) or space.dtype.kind != "f" or not space.is_bounded("both"):
        return None
    return space.low.ravel().copy(), space.high.ravel().copy()
