"""Native vector Buckybot environments: parity with the single env, autoreset, metrics, errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import polyenvs
from tests.vector_helpers import assert_native_matches_sync

IDS = [env_id for env_id in polyenvs.ENV_IDS if "Buckybot" in env_id]  # other families test their own


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_defaults_to_the_native_vector_env(env_id):
    envs = gym.make_vec(env_id, num_envs=3)
    assert type(envs).__name__.endswith("VectorEnv") and envs.num_envs == 3
    obs, info = envs.reset(seed=0)
    assert obs.shape == (3, *envs.single_observation_space.shape) and obs.dtype == np.float32
    assert envs.observation_space.contains(obs)
    assert info["action_mask"].shape == (3, 3) and info["action_mask"].dtype == np.int8
    envs.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("env_id", IDS)
def test_native_vector_env_matches_sync_vector_env_in_random_rooms(env_id, mode):
    """The registry-wide parity test (tests/test_envs_shared.py) on Buckybot's own variant: a random room per
    sub-environment, drawn from its seed."""
    assert assert_native_matches_sync(env_id, mode, floor_plan="random") >= 8  # every row autoreset at least twice


def test_vector_env_rows_match_single_envs_seeded_s_plus_i():
    vector = gym.make_vec(IDS[2], num_envs=3, vectorization_mode="vector_entry_point")
    obs_v, info_v = vector.reset(seed=20)
    for i in range(3):
        obs, info = gym.make(IDS[2]).reset(seed=20 + i)
        assert np.array_equal(obs, obs_v[i]) and np.array_equal(info["goal"], info_v["goal"][i])


def test_vector_env_refuses_use_after_close():
    envs = gym.make_vec(IDS[0], num_envs=2)
    envs.reset(seed=0)
    envs.close()
    with pytest.raises(gym.error.ClosedEnvironmentError):
        envs.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(gym.error.ClosedEnvironmentError):
        envs.reset(seed=0)


def test_vector_env_renders_sub_environment_0():
    envs = gym.make_vec(IDS[0], num_envs=3, render_mode="rgb_array", floor_plan="random")
    single = gym.make(IDS[0], render_mode="rgb_array", floor_plan="random")
    envs.reset(seed=4)
    single.reset(seed=4)
    assert np.array_equal(envs.render(), single.render())
    for action in (1, 2, 1):
        envs.step(np.array([action, 0, 0]))
        single.step(action)
    assert np.array_equal(envs.render(), single.render())


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
    [
        ({"num_envs": 0}, "num_envs"),
        ({"num_envs": True}, "num_envs"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
        ({"render_mode": "human"}, "render_mode"),
        ({"autoreset_mode": "sometimes"}, "autoreset_mode"),
        ({"noise_scale": -1}, "noise_scale"),
    ],
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
