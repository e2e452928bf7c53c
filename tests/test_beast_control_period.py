"""The beasts' control period (``control_timestep``): an action held for a whole number of 10 ms ticks.

A step of a k-tick env must be exactly k steps of the 10 ms env with the action repeated: the same simulation, the
same observation at the same simulated time, the same metrics, the ticks' rewards summed.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.beast import sensors as S
from polyenvs.beast.tasks import BeastRollV1Env, BeastTumbleEnv

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _held_actions(env, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    start = env.unwrapped.control_to_action(env.unwrapped._joints[S.HOLD])  # near the start pose
    return [np.clip(start + rng.normal(0, 0.05, start.shape), -1, 1).astype(np.float32) for _ in range(n)]


@pytest.mark.parametrize(("env_cls", "ticks"), [(BeastRollV1Env, 5), (BeastTumbleEnv, 3)])
def test_a_held_action_is_the_10_ms_env_repeating_it(env_cls, ticks):
    fine, coarse = env_cls(), env_cls(control_timestep=0.01 * ticks)
    assert coarse.ticks_per_step == ticks and coarse.dt == pytest.approx(0.01 * ticks)
    for seed in (0, 1):
        fine_obs, _ = fine.reset(seed=seed)
        coarse_obs, _ = coarse.reset(seed=seed)
        np.testing.assert_array_equal(fine_obs, coarse_obs)
        for action in _held_actions(coarse, 40, seed):
            rewards, terms = [], []
            for _ in range(ticks):
                fine_obs, reward, fine_done, fine_cut, fine_info = fine.step(action)
                rewards.append(reward)
                terms.append([fine_info[k] for k in fine._reward_keys])
                if fine_done or fine_cut:
                    break
            coarse_obs, reward, done, cut, info = coarse.step(action)
            np.testing.assert_array_equal(coarse_obs, fine_obs)
            np.testing.assert_array_equal(coarse.data.qpos, fine.data.qpos)
            assert (done, cut) == (fine_done, fine_cut)
            assert reward == pytest.approx(sum(rewards), rel=1e-12, abs=1e-15)
            assert [info[k] for k in coarse._reward_keys] == pytest.approx(np.sum(terms, axis=0).tolist(), rel=1e-12)
            assert coarse.episode_metrics() == fine.episode_metrics()
            assert info.get("episode_metrics") == fine_info.get("episode_metrics")
            if done or cut:
                break


def test_50_ms_takes_five_times_fewer_steps_for_the_same_simulated_time():
    fine = gym.make("polyenvs/BeastRoll-v1", max_episode_steps=400)
    coarse = gym.make("polyenvs/BeastRoll-v1", control_timestep=0.05, max_episode_steps=400 // 5)
    lengths, times = [], []
    for env in (fine, coarse):
        env.reset(seed=3)
        action = env.unwrapped.control_to_action(env.unwrapped.data.ctrl)
        steps, truncated = 0, False
        while not truncated:
            _, _, _, truncated, info = env.step(action)
            steps += 1
        lengths.append(steps)
        times.append(env.unwrapped._elapsed * 0.01)
    assert lengths == [400, 80]
    assert times[0] == times[1] == pytest.approx(4.0)
    assert coarse.unwrapped.metadata["render_fps"] == 20 and fine.unwrapped.metadata["render_fps"] == 100


def test_the_default_is_the_10_ms_tick():
    env = BeastTumbleEnv()
    assert env.control_timestep == 0.01 and env.ticks_per_step == 1 and env.dt == 0.01
    explicit = BeastTumbleEnv(control_timestep=0.01)
    a, _ = env.reset(seed=5)
    b, _ = explicit.reset(seed=5)
    action = env.action_space.sample() * 0
    for _ in range(30):
        a, ra, *_ = env.step(action)
        b, rb, *_ = explicit.step(action)
        assert ra == rb
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("bad", [0.0, -0.02, 0.005, 0.015, 0.11, 0.2, float("nan"), True, "0.02"])
def test_bad_control_timesteps_raise_naming_it(bad):
    with pytest.raises(ValueError, match="control_timestep"):
        BeastRollV1Env(control_timestep=bad)


def test_the_control_period_is_documented():
    doc = BeastRollV1Env.__doc__
    assert "| control_timestep | 0.01 |" in doc and "in [0.01, 0.1] s" in doc
    assert "## Control period" in doc and "max_episode_steps" in doc
