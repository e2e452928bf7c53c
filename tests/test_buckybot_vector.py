"""Native vector Buckybot environments: parity with the single env, autoreset, metrics, errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import polyenvs

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


def _assert_same(a, b, where=""):
    """Recursive bit-for-bit equality of vector-env outputs (arrays, object arrays, nested info dicts)."""
    if isinstance(a, dict):
        assert set(a) == set(b), f"{where}: keys differ: {set(a) ^ set(b)}"
        for key in a:
            _assert_same(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, where
        for i, (x, y) in enumerate(zip(a.tolist(), b.tolist(), strict=True)):
            if isinstance(x, np.ndarray):
                _assert_same(x, y, f"{where}[{i}]")
            else:
                assert x == y, where
    else:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}"
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), where


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("floor_plan", [None, "random"])
@pytest.mark.parametrize("env_id", IDS)
def test_native_vector_env_matches_sync_vector_env(env_id, floor_plan, mode):
    """Sub-env i reset with seed s is gym.make(id) reset with seed s + i, bit for bit, through autoresets, in both
    of Gymnasium's autoreset modes (same-step: with final_obs and final_info)."""
    kwargs = {} if floor_plan is None else {"floor_plan": floor_plan}
    make = {"num_envs": 4, "max_episode_steps": 30, **kwargs}
    native = gym.make_vec(env_id, vectorization_mode="vector_entry_point", autoreset_mode=mode, **make)
    sync = gym.make_vec(env_id, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **make)
    assert native.metadata["autoreset_mode"] == mode
    _assert_same(native.reset(seed=11), sync.reset(seed=11), "reset")
    rng = np.random.default_rng(0)
    ended = 0
    for t in range(75):
        actions = rng.integers(3, size=4)
        result = native.step(actions)
        _assert_same(result, sync.step(actions), f"step {t}")
        ended += int((result[2] | result[3]).sum())
    assert ended >= 8  # every row went through at least two autoresets
    # A second seeded reset, with a list of seeds as SyncVectorEnv takes them.
    _assert_same(native.reset(seed=[3, None, 5, 6]), sync.reset(seed=[3, None, 5, 6]), "list reset")
    native.close()
    sync.close()


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
