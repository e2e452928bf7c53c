"""The batched swarm (E environments x N robots as one vector env) against the PettingZoo environment it batches."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.swarm import APLiteGoalSeeking, FormationController
from polyenvs.swarm import corridor_v0, formation_v0, obstacle_field_v0
from polyenvs.swarm.batched import SwarmVectorEnv

MODULES = {"corridor_v0": corridor_v0, "obstacle_field_v0": obstacle_field_v0, "formation_v0": formation_v0}


@pytest.mark.parametrize("task", list(MODULES))
def test_each_batched_environment_is_the_single_environment_bit_for_bit(task):
    """Environment e of the batch reset with seed s reproduces ``parallel_env`` reset with seed s + e: observations,
    rewards and episode ends, through autoresets (short episodes, so several happen)."""
    kwargs = {"n_robots": 3, "max_cycles": 25}
    if task == "corridor_v0":
        kwargs["max_cycles"] = 260  # long enough for robots to arrive and leave
    n_envs, steps, seed = 3, 300, 11
    batch = SwarmVectorEnv(task, num_envs=n_envs, **kwargs)
    singles = [MODULES[task].parallel_env(**kwargs) for _ in range(n_envs)]
    policy_cls = FormationController if task == "formation_v0" else APLiteGoalSeeking
    space = batch.single_observation_space
    policy = policy_cls(space, batch.single_action_space, platform=batch.task.platform.name, sensors=(0, 1, 2, 3))
    obs, _ = batch.reset(seed=seed)
    single_obs = [env.reset(seed=seed + e)[0] for e, env in enumerate(singles)]
    rng = np.random.default_rng(0)
    ends = arrivals = 0
    for _ in range(steps):
        for e, env in enumerate(singles):
            for a, o in single_obs[e].items():
                assert np.array_equal(obs[e * 3 + env.agent_name_mapping[a]], o)
        actions, _ = policy.predict(obs)
        actions = np.clip(actions + 0.05 * rng.standard_normal(actions.shape), -1, 1).astype(np.float32)
        obs, rewards, terminated, truncated, infos = batch.step(actions)
        for e, env in enumerate(singles):
            live = list(env.agents)
            step_obs, step_rewards, step_term, step_trunc, _ = env.step(
                {a: actions[e * 3 + env.agent_name_mapping[a]] for a in live}
            )
            for a in live:
                row = e * 3 + env.agent_name_mapping[a]
                assert rewards[row] == step_rewards[a]
                arrivals += step_term[a]
            if not env.agents:  # the episode ended: the batch has reset this environment in the same step
                ends += 1
                rows = slice(e * 3, e * 3 + 3)
                assert infos["_final_obs"][rows].all()
                for a, o in step_obs.items():
                    assert np.array_equal(infos["final_obs"][e * 3 + env.agent_name_mapping[a]], o)
                metrics = env.episode_metrics()
                for k, v in metrics.items():
                    assert infos["final_info"]["episode_metrics"][k][e * 3] == pytest.approx(v, rel=1e-12, abs=1e-12)
                assert (terminated[rows] | truncated[rows]).all()
                single_obs[e] = env.reset()[0]
            else:
                single_obs[e] = step_obs
                assert not (terminated[e * 3 : e * 3 + 3] | truncated[e * 3 : e * 3 + 3]).any()
    assert ends >= n_envs
    if task == "corridor_v0":
        assert arrivals > 0


def test_batched_rows_of_departed_robots_read_zero_and_bad_actions_raise():
    batch = SwarmVectorEnv("corridor_v0", num_envs=2, n_robots=2)
    obs, _ = batch.reset(seed=0)
    assert obs.shape == (4, batch.single_observation_space.shape[0]) and batch.observation_space.contains(obs)
    pose = batch.pose.copy()
    for bad in (np.full((4, 2), np.nan), np.zeros((3, 2)), np.full((4, 2), 1.5)):
        with pytest.raises(ValueError, match="actions"):
            batch.step(bad)
        assert np.array_equal(batch.pose, pose)
    batch.active[1] = 0  # robot 1 of environment 0 has left
    obs, rewards, *_ = batch.step(np.full((4, 2), 0.5, np.float32))
    assert not obs[1].any() and rewards[1] == 0.0 and obs[0].any()
    with pytest.raises(ValueError, match="task"):
        SwarmVectorEnv("pistonball", num_envs=2)
    with pytest.raises(ValueError, match="num_envs"):
        SwarmVectorEnv("corridor_v0", num_envs=0)


def test_batched_swarm_trains_with_ppo_through_the_native_adapter():
    """Parameter sharing at scale: the batched swarm as an SB3 VecEnv of robots (same-step autoreset), seeded."""
    sb3 = pytest.importorskip("stable_baselines3")
    import torch

    from polyenvs.training.vec_adapter import NativeVecEnvAdapter

    torch.set_num_threads(1)
    venv = NativeVecEnvAdapter(SwarmVectorEnv("corridor_v0", num_envs=4, n_robots=2, max_cycles=30))
    model = sb3.PPO("MlpPolicy", venv, n_steps=32, batch_size=128, n_epochs=1, seed=0, verbose=0)
    model.learn(512)
    assert model.num_timesteps >= 512
    venv.close()
