"""Native vector Buckybot environments: parity with the single env, autoreset, metrics, errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs

IDS = polyenvs.ENV_IDS


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_defaults_to_the_native_vector_env(env_id):
    envs = gym.make_vec(env_id, num_envs=3)
    assert type(envs).__name__.endswith("VectorEnv") and envs.num_envs == 3
    obs, info = envs.reset(seed=0)
    assert obs.shape == (3, *envs.single_observation_space.shape) and obs.dtype == np.float32
    assert envs.observation_space.contains(obs)
    assert info["action_mask"].shape == (3, 3) and info["action_mask"].dtype == np.int8
    envs.close()


@pytest.mark.parametrize("env_id", IDS)
def test_one_robot_vector_env_matches_the_single_env(env_id):
    """Parity: the same seed and actions give the single env's first episode bit for bit."""
    single = gym.make(env_id)
    vector = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point")
    obs_s, _ = single.reset(seed=11)
    obs_v, _ = vector.reset(seed=11)
    assert np.array_equal(obs_s, obs_v[0])
    rng = np.random.default_rng(0)
    for _ in range(gym.spec(env_id).max_episode_steps):
        action = int(rng.integers(3))
        obs_s, reward_s, term_s, trunc_s, info_s = single.step(action)
        obs_v, reward_v, term_v, trunc_v, info_v = vector.step(np.array([action]))
        assert np.array_equal(obs_s, obs_v[0])
        assert reward_s == reward_v[0] and term_s == term_v[0] and trunc_s == trunc_v[0]
        assert np.array_equal(info_s["action_mask"], info_v["action_mask"][0])
        if term_s or trunc_s:
            for name, value in info_s["episode_metrics"].items():
                assert info_v["episode_metrics"][name][0] == pytest.approx(value)
            break


def test_autoreset_next_step():
    envs = gym.make_vec(IDS[0], num_envs=4, max_episode_steps=5)
    envs.reset(seed=1)
    for _ in range(4):
        _, _, _, truncated, info = envs.step(np.zeros(4, dtype=np.int64))
        assert not truncated.any() and "episode_metrics" not in info
    _, _, terminated, truncated, info = envs.step(np.ones(4, dtype=np.int64))
    assert truncated.all() and not terminated.any()
    assert info["_episode_metrics"].all() and np.isfinite(info["episode_metrics"]["wall_distance_error_cm"]).all()
    obs, rewards, terminated, truncated, _ = envs.step(np.ones(4, dtype=np.int64))
    assert (rewards == 0).all() and not (terminated | truncated).any()  # this step only reset them
    assert envs.observation_space.contains(obs)
    assert (envs.unwrapped._core.steps == 0).all()


def test_vector_env_is_deterministic_and_stays_in_its_space():
    def run(seed):
        envs = gym.make_vec(IDS[1], num_envs=8, max_episode_steps=50)
        envs.action_space.seed(seed)
        obs, _ = envs.reset(seed=seed)
        trace = [obs]
        for _ in range(120):
            obs, rewards, *_ = envs.step(envs.action_space.sample())
            assert envs.observation_space.contains(obs)
            trace.append(obs)
        return np.stack(trace)

    assert np.array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))


@pytest.mark.parametrize(
    "kwargs, name",
    [({"num_envs": 0}, "num_envs"), ({"floor_plan": "random"}, "random"), ({"noise_scale": -1}, "noise_scale")],
)
def test_bad_vector_arguments(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make_vec(IDS[0], **{"num_envs": 2, **kwargs})


def test_bad_vector_actions():
    envs = gym.make_vec(IDS[2], num_envs=2)
    envs.reset(seed=0)
    for bad in (np.array([0, 3]), np.array([0]), np.array([0.0, 1.0]), np.array([-1, 0])):
        with pytest.raises(ValueError, match="actions"):
            envs.step(bad)
