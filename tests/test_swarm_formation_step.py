"""The formation's terms run in its compiled step (issue 33): what they write after each step is, bit for bit, what
the numpy formulas give from the state the step left (the robots that took it, the environments that stepped), in
a batch whose autoresets mask environments out of steps."""

from __future__ import annotations

import numpy as np

from polyenvs.swarm.batch import INFO_REWARD
from polyenvs.swarm.batched import SwarmVectorEnv
from polyenvs.swarm.formation_v0 import FORMATION_HOLDS_ERROR, FORMATION_PENALTY, formation_error


def _expected(batch, before: dict) -> dict:
    """The formation's terms after a step, from numpy: ``before`` holds the running sums before it."""
    terms, live, rows, envs = batch.terms, batch.live, batch._todo > 0, batch._stepping > 0
    per_robot, count, swarm = np.zeros(batch.n_rows), np.zeros(batch.n_rows), np.zeros(batch.n_envs)
    formation_error(batch.pose, live, terms.pairs, terms.spacing_m, per_robot, count, swarm)
    centroid = batch.pose[:, :2].reshape(batch.n_envs, batch.n_robots, 2).mean(axis=1)
    distance = np.hypot(*(centroid - batch.goals).T)
    progress = np.where(swarm <= FORMATION_HOLDS_ERROR, before["centroid_distance"] - distance, 0.0)
    reward = np.where(live, -FORMATION_PENALTY * per_robot, 0.0)
    return {
        "per_robot": np.where(rows, per_robot, before["per_robot"]),
        "reward": np.where(rows, reward, before["reward"]),
        "robot_sum": np.where(rows, before["robot_sum"] + np.where(live, per_robot, 0.0), before["robot_sum"]),
        "swarm_sum": np.where(envs, before["swarm_sum"] + swarm, before["swarm_sum"]),
        "progress_sum": np.where(envs, before["progress_sum"] + progress, before["progress_sum"]),
        "centroid_distance": np.where(envs, distance, before["centroid_distance"]),
    }


def _terms(batch) -> dict:
    terms = batch.terms
    return {
        "per_robot": terms.per_robot.copy(),
        "reward": batch.rewards[:, batch.reward_column("formation")].copy(),
        "robot_sum": terms.robot_sum.copy(),
        "swarm_sum": terms.swarm_sum.copy(),
        "progress_sum": terms.progress_sum.copy(),
        "centroid_distance": terms.centroid_distance.copy(),
    }


def test_the_formation_terms_of_the_compiled_step_are_the_numpy_formulas_bit_for_bit():
    env = SwarmVectorEnv("formation_v0", num_envs=3, n_robots=7, max_cycles=12, terminate_on_collision=True,
                         spacing_m=0.5)  # fmt: skip
    env.reset(seed=4)
    batch, rng = env.batch, np.random.default_rng(0)
    masked = 0
    for _ in range(40):
        before = _terms(batch)
        # The batch's own step, as the vector env takes it (its autoresets step the other environments only).
        stepping = rng.random(batch.n_envs) < 0.7
        batch.step(rng.uniform(-1, 1, (batch.n_rows, 2)), stepping)
        masked += int(not stepping.all())
        expected, got = _expected(batch, before), _terms(batch)
        for name in expected:
            assert np.array_equal(got[name], expected[name]), name
        assert np.array_equal(batch.info_table[:, INFO_REWARD], batch.rewards.sum(axis=1))
    assert masked > 5
