"""How much room ``polyenvs/BumperCartLocalize-v0`` leaves a policy: cycles to localize of random, the upper anchor
``greedy_split``, and two planners that cheat, which no policy can beat by choosing turns better.

The cheats are diagnostics, not baselines: they read the environment's hidden state. ``env_belief`` plans
``greedy_split``'s one-step split on the environment's own particles (the belief the task judges) instead of the
policy's copy; ``env_belief_and_truth`` adds the true pose to those particles as a hypothesis of half their mass,
so it picks the turn that best tells the truth from the environment's current belief. ``random, no bump slip``
is random in the same environment with the cart's bump slips off (``snap_prob=0, slide_prob=0``): how much of the
episode's length is the slips the filter cannot see.

``python -m benchmarks.localize_headroom [--seeds 0-29]`` prints a Markdown table (IQM and 95% interval, as the
leaderboard aggregates the score). Tune on seeds other than the leaderboard's (1000-1049).
"""

from __future__ import annotations

import argparse
import math

import gymnasium as gym
import numpy as np

from baselines.base import RandomPolicy
from baselines.bumper import GreedySplit
from polyenvs.bumper import cart as C
from polyenvs.evaluation.statistics import iqm_with_ci

__all__ = ["ENV_ID", "EnvBeliefSplit", "cycles_to_localize", "main"]

ENV_ID = "polyenvs/BumperCartLocalize-v0"
#: Turns the cheating planners consider (``greedy_split`` considers 12).
CANDIDATES = 24


class EnvBeliefSplit(GreedySplit):
    """``greedy_split``'s split, planned on the environment's own particles (and, with ``truth``, the true pose)."""

    def __init__(self, observation_space, action_space, env, truth: bool = False, seed: int | None = 0):
        super().__init__(observation_space, action_space, candidates=CANDIDATES, seed=seed)
        self.env, self.truth = env.unwrapped, truth

    def split_informations(self, particles: np.ndarray) -> np.ndarray:
        believed = self.env._particles[0]
        if self.truth:
            row = self.env.state[0]
            pose = np.tile([row[C.X], row[C.Y], row[C.HEADING]], (len(believed) // 2, 1))
            believed = np.concatenate([believed, pose])
        return super().split_informations(np.ascontiguousarray(believed))


def cycles_to_localize(env, policy, seeds) -> list[float]:
    """The score of ``policy`` in one episode per seed."""
    scores = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        state, start, done = None, True, False
        while not done:
            action, state = policy.predict(obs, state=state, episode_start=[start])
            obs, _, terminated, truncated, _ = env.step(action)
            start, done = False, terminated or truncated
        scores.append(env.unwrapped.episode_metrics()["cycles_to_localize"])  # the time limit's end too
    return scores


def _rows(seeds):
    env = gym.make(ENV_ID)
    space = (env.observation_space, env.action_space)
    no_slip = gym.make(ENV_ID, snap_prob=0.0, slide_prob=0.0)
    yield "random", env, RandomPolicy(*space, seed=seeds[0])
    yield "greedy_split", env, GreedySplit(*space, seed=seeds[0])
    yield "env_belief (cheat)", env, EnvBeliefSplit(*space, env, seed=seeds[0])
    yield "env_belief_and_truth (cheat)", env, EnvBeliefSplit(*space, env, truth=True, seed=seeds[0])
    yield "random, no bump slip", no_slip, RandomPolicy(*space, seed=seeds[0])


def _seed_range(text: str) -> list[int]:
    first, _, last = text.partition("-")
    if not (first.isdigit() and last.isdigit()) or int(last) < int(first):
        raise argparse.ArgumentTypeError(f"--seeds must be FIRST-LAST, got {text!r}")
    return list(range(int(first), int(last) + 1))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=_seed_range, default=_seed_range("0-29"), help="FIRST-LAST (default 0-29)")
    seeds = parser.parse_args(argv).seeds
    print(f"| policy ({ENV_ID}, seeds {seeds[0]}-{seeds[-1]}) | cycles_to_localize IQM [95% CI] | mean |")
    print("| --- | --- | --- |")
    for name, env, policy in _rows(seeds):
        scores = cycles_to_localize(env, policy, seeds)
        value, low, high = iqm_with_ci(scores)
        print(f"| {name} | {value:.3g} [{low:.3g}, {high:.3g}] | {math.fsum(scores) / len(scores):.3g} |", flush=True)


if __name__ == "__main__":
    main()
