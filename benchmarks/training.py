"""Training speed: Stable-Baselines3 PPO timesteps/s on our environments against PPO on CartPole-v1.

The spec's target is that the environment is never the bottleneck (>= 0.8x PPO on CartPole). The PPO rows are timed
in interleaved rounds like the step rows (CartPole, then ours, the order reversed every other round), each round
running rollouts and gradient epochs, as a user training on the environment pays both.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym

from benchmarks.harness import Case, Measurement, measure_rounds
from benchmarks.peers import CARTPOLE
from benchmarks.targets import Kind, target_for

__all__ = ["PPO_SETTING", "PPORunner", "measure_training"]

_N_STEPS = 512
PPO_SETTING = f"SB3 PPO MlpPolicy, 1 env, n_steps {_N_STEPS}, 4 epochs (timesteps/s)"


class PPORunner:
    """A PPO model on one ``gym.make`` env; each repeat learns ``timesteps`` more and returns timesteps/s."""

    num_envs = 1
    vector = False

    def __init__(self, env_id: str, *, timesteps: int, seed: int = 0) -> None:
        import torch
        from stable_baselines3 import PPO

        torch.set_num_threads(1)  # two threads on these 2-core machines are intermittently 10-100x slower
        self.timesteps = timesteps
        self.env = gym.make(env_id)
        self.model = PPO(
            "MlpPolicy", self.env, n_steps=_N_STEPS, batch_size=64, n_epochs=4, seed=seed, device="cpu", verbose=0
        )

    def warm_up(self) -> None:
        """One rollout and its epochs: compilation, torch's lazy set-up."""
        self.model.learn(total_timesteps=_N_STEPS)

    def timed_repeat(self) -> float:
        start = time.perf_counter()
        self.model.learn(total_timesteps=self.timesteps, reset_num_timesteps=False)
        return self.timesteps / (time.perf_counter() - start)

    def close(self) -> None:
        self.env.close()


def measure_training(
    env_ids: Sequence[str], *, timesteps: int, repeats: int, seed: int = 0
) -> tuple[list[Measurement], list[str]]:
    """PPO on CartPole-v1 and on each id of ``env_ids`` that has a PPO target, in rounds; and notes."""
    missing = [name for name in ("torch", "stable_baselines3") if not _imports(name)]
    if missing:
        return [], [f'training speed skipped: {", ".join(missing)} not installed (pip install "polyenvs[train]")']
    ids = [CARTPOLE, *(env_id for env_id in env_ids if target_for(env_id, Kind.PPO) is not None)]
    cases = [Case(env_id, PPO_SETTING, start=_starter(env_id, timesteps, seed)) for env_id in ids]
    return measure_rounds(cases, repeats=repeats), []


def _starter(env_id: str, timesteps: int, seed: int) -> Any:
    return lambda: PPORunner(env_id, timesteps=timesteps, seed=seed)


def _imports(module: str) -> bool:
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
