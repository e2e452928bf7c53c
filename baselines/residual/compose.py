"""What a residual agent corrects (:class:`ResidualSpec`) and its baseline with the arithmetic around it
(:class:`ResidualComposer`): the half that the environment wrappers (:mod:`baselines.residual.wrappers`) and the
loaded agents (:mod:`baselines.trained`) share. How it composes, and why: :mod:`baselines.residual`."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from gymnasium import spaces

from baselines.factory import available_policies, make_baseline
from baselines.tuned import is_tuned_path, load_tuned_policy
from polyenvs.core.validation import check_bool, check_in_range, check_int

__all__ = ["MAX_HOLD", "MAX_SCALE", "ResidualComposer", "ResidualSpec", "make_composer"]

#: The largest scale: a residual of +-1 then moves an action across the whole [-1, 1] range from either end.
MAX_SCALE = 2.0
#: The longest hold, in control ticks: one decision a second at the beasts' 10 ms.
MAX_HOLD = 100


@dataclasses.dataclass(frozen=True)
class ResidualSpec:
    """What a residual agent corrects: ``baseline`` (a hand baseline's name, or ``"paper"``), ``scale`` (in
    ``(0, 2]``: the correction is ``scale x residual``), ``observe_base`` (the agent sees the base action) and
    ``hold`` (the correction is held for this many control ticks, 1 to :data:`MAX_HOLD`)."""

    baseline: str = "paper"
    scale: float = 0.5
    observe_base: bool = True
    hold: int = 1

    def __post_init__(self):
        if not isinstance(self.baseline, str) or not self.baseline:
            raise ValueError(f"baseline must be a baseline's name, got {self.baseline!r}")
        object.__setattr__(self, "scale", check_in_range("scale", self.scale, 0.0, MAX_SCALE, low_open=True))
        object.__setattr__(self, "observe_base", check_bool("observe_base", self.observe_base))
        object.__setattr__(self, "hold", check_int("hold", self.hold, 1, MAX_HOLD))

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, document) -> ResidualSpec:
        """The spec a run.json's ``residual`` entry records (without ``hold``: 1, as runs before it were);
        ``ValueError`` for anything else."""
        if not isinstance(document, dict) or set(document) - {f.name for f in dataclasses.fields(cls)}:
            raise ValueError(f"residual must be an object of baseline, scale, observe_base and hold, got {document!r}")
        return cls(**document)


class ResidualComposer:
    """The baseline of a residual agent and the arithmetic around it.

    Args:
        spec: the baseline, the scale and whether the agent observes the base action.
        base: the baseline's policy (``predict`` with a ``state``, :mod:`baselines.base`).
        observation_space, action_space: the environment's (one robot's, for a PettingZoo swarm).
    """

    def __init__(self, spec: ResidualSpec, base, observation_space: spaces.Box, action_space: spaces.Box):
        self.spec, self.base = spec, base
        self.env_observation_space, self.env_action_space = observation_space, action_space
        #: The agent's actions: a correction in [-1, 1] per dimension, before ``scale``.
        self.action_space = spaces.Box(-1.0, 1.0, action_space.shape, np.float32)
        self.observation_space = self._agent_observation_space() if spec.observe_base else observation_space

    def _agent_observation_space(self) -> spaces.Box:
        obs, act = self.env_observation_space, self.env_action_space
        low = np.concatenate([obs.low.ravel(), act.low.astype(obs.dtype).ravel()])
        high = np.concatenate([obs.high.ravel(), act.high.astype(obs.dtype).ravel()])
        return spaces.Box(low, high, dtype=obs.dtype)

    def base_action(self, observation, state, episode_start) -> tuple[np.ndarray, Any]:
        """``(the baseline's action, its new state)``; ``episode_start`` restarts its memory where true."""
        action, state = self.base.predict(observation, state=state, episode_start=episode_start, deterministic=True)
        return np.asarray(action), state

    def observe(self, observation, base_action: np.ndarray) -> np.ndarray:
        """What the agent sees: the observation, with the base action appended when ``observe_base``."""
        if not self.spec.observe_base:
            return observation
        observation = np.asarray(observation)
        return np.concatenate([observation, base_action.astype(observation.dtype, copy=False)], axis=-1)

    def combine(self, base_action: np.ndarray, residual) -> np.ndarray:
        """``clip(base + scale x residual, low, high)`` in the base action's dtype (a zero residual: the base)."""
        base = np.asarray(base_action)
        correction = self.spec.scale * np.asarray(residual, dtype=base.dtype)
        combined = np.clip(base + correction, self.env_action_space.low, self.env_action_space.high)
        return combined.astype(base.dtype, copy=False)

    def act(self, observation, state, episode_start, correct) -> tuple[np.ndarray, np.ndarray]:
        """``(action, state)`` of a residual agent called every control tick, in ``predict``'s convention (one
        observation or a batch, ``episode_start`` per row).

        ``correct(agent_observations)`` is the agent's network (a batch of what :meth:`observe` gives -> a batch of
        corrections); it is asked only for the rows whose hold is over (every ``hold`` ticks since the episode
        started) and its correction is held in between, while the baseline acts on every tick. A ``state`` row is
        the baseline's memory, then the held correction, then the ticks since the episode started (float64: the
        corrections are float32, the counts small integers, both exact)."""
        obs = np.asarray(observation)
        single = obs.shape == self.env_observation_space.shape
        batch = obs[None] if single else obs
        n = batch.shape[0]
        memory, held, ticks = self._unpack(state, n)
        start = np.zeros(n, bool) if episode_start is None else np.broadcast_to(np.asarray(episode_start, bool), (n,))
        ticks[start] = 0
        base, memory = self.base_action(batch, memory, start)
        due = ticks % self.spec.hold == 0
        if due.any():
            held[due] = np.asarray(correct(self.observe(batch[due], base[due]))).reshape(int(due.sum()), -1)
        action = self.combine(base, held.reshape(base.shape))
        state = np.column_stack([np.asarray(memory, np.float64).reshape(n, -1), held, ticks + 1])
        return (action[0] if single else action), state

    def _unpack(self, state, n: int) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """``(baseline memory or None, held corrections, ticks)`` of ``n`` rows of :meth:`act`'s state."""
        width = int(np.prod(self.action_space.shape))
        if state is None:
            return None, np.zeros((n, width)), np.zeros(n)
        state = np.array(state, dtype=np.float64).reshape(n, -1)
        return state[:, : -width - 1], state[:, -width - 1 : -1], state[:, -1]

    def describe(self) -> dict[str, Any]:
        return {**self.spec.to_json(), "base": self.base.describe()}


def make_composer(
    spec: ResidualSpec, env_id: str, observation_space, action_space, seed: int | None = None
) -> ResidualComposer:
    """The composer of ``spec`` for ``env_id``: ``ValueError`` naming the parameter for an action space that is not
    a Box (``env``), a ``baseline`` that is not one of the id's hand baselines or a tuned one's directory
    (``polyenvs tune``'s; random and trained models are not bases: a residual corrects a fixed, known controller) or a ``seed`` that is not ``None`` or an integer >= 0
    (it seeds a stochastic baseline)."""
    if seed is not None:
        check_int("seed", seed, 0)
    if not isinstance(action_space, spaces.Box) or not isinstance(observation_space, spaces.Box):
        kinds = " and ".join(f"Box{s.shape}" if isinstance(s, spaces.Box) else str(s)
                             for s in (observation_space, action_space))  # fmt: skip
        raise ValueError(f"env: a residual policy needs Box observations and actions, {env_id} has {kinds}")
    choices = [name for name in available_policies(env_id) if name != "random"]
    if is_tuned_path(spec.baseline):
        base = load_tuned_policy(spec.baseline, env_id, observation_space, action_space, seed=seed)
    elif spec.baseline in choices:
        base = make_baseline(spec.baseline, env_id, observation_space, action_space, seed=seed)
    else:
        raise ValueError(
            f"baseline {spec.baseline!r} is not a hand baseline of {env_id} nor a tuned one's directory; "
            f"choose from {choices}"
        )
    return ResidualComposer(spec, base, observation_space, action_space)
