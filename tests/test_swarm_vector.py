"""Native vector envs of the single-robot swarm ids: parity with SyncVectorEnv over gym.make, autoreset, errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from baselines.swarm import APLiteGoalSeeking
from polyenvs.core.episode_metrics import RecordEpisodeMetrics
from polyenvs.registry import REGISTRY
from polyenvs.swarm.vector import SingleRobotVectorEnv
from tests.vector_helpers import assert_same as _assert_same

IDS = [e.id for e in REGISTRY if e.kind == "gymnasium" and e.family == "swarm"]


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_defaults_to_the_native_vector_env(env_id):
    envs = gym.make_vec(env_id, num_envs=3)
    assert isinstance(envs, SingleRobotVectorEnv) and envs.num_envs == 3
    obs, info = envs.reset(seed=0)
    assert obs.shape == (3, *envs.single_observation_space.shape) and obs.dtype == np.float32
    assert envs.observation_space.contains(obs)
    assert info["pose"].shape == (3, 3) and "episode_metrics" not in info  # only on the rows whose episode ended
    envs.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("env_id", IDS)
def test_native_vector_env_matches_sync_vector_env_as_robots_arrive(env_id, mode):
    """The registry-wide parity test (tests/test_envs_shared.py) drives at random; here the goal-seeking baseline
    with noise drives, so robots arrive (terminated) and others run out of time (truncated)."""
    make = {"num_envs": 4, "max_episode_steps": 200}
    if env_id.endswith("ObstacleField-v0"):
        make.update(n_obstacles=0, goal_radius_m=1.5)
    native = gym.make_vec(env_id, vectorization_mode="vector_entry_point", autoreset_mode=mode, **make)
    sync = gym.make_vec(
        env_id,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        wrappers=[RecordEpisodeMetrics],
        **make,
    )
    assert native.metadata["autoreset_mode"] == mode
    obs, info = native.reset(seed=11)
    _assert_same((obs, info), sync.reset(seed=11), "reset")
    platform = native.task.platform
    policy = APLiteGoalSeeking(native.single_observation_space, native.single_action_space, platform=platform.name)
    rng = np.random.default_rng(0)
    state, terminated, truncated = None, 0, 0
    for t in range(450):
        actions, state = policy.predict(obs, state)
        actions = np.clip(actions + 0.2 * rng.standard_normal(actions.shape), -1, 1).astype(np.float32)
        result = native.step(actions)
        _assert_same(result, sync.step(actions), f"step {t}")
        obs, done = result[0], result[2] | result[3]
        state = np.where(done[:, None], policy.initial_memory(), state)
        terminated += int(result[2].sum())
        truncated += int((result[3] & ~result[2]).sum())
    assert terminated >= 1 and truncated >= 2  # robots arrived, others ran out of time
    # A second seeded reset, with a list of seeds as SyncVectorEnv takes them (None: the sub-env's own generator).
    _assert_same(native.reset(seed=[3, None, 5, 6]), sync.reset(seed=[3, None, 5, 6]), "list reset")
    for t in range(5):
        actions = rng.uniform(-1, 1, (4, 2))  # float64: taken as float32, as the single env takes them
        _assert_same(native.step(actions), sync.step(actions), f"after the list reset, step {t}")
    native.close()
    sync.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_arrival_on_the_last_step_is_terminated_and_truncated_as_time_limit_says(mode):
    """Gymnasium's TimeLimit truncates on its last step even when the episode also terminates there."""
    make = {"num_envs": 2, "max_episode_steps": 3}
    native = gym.make_vec(IDS[0], vectorization_mode="vector_entry_point", autoreset_mode=mode, **make)
    sync = gym.make_vec(
        IDS[0],
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        wrappers=[RecordEpisodeMetrics],
        **make,
    )
    _assert_same(native.reset(seed=2), sync.reset(seed=2), "reset")
    still = np.zeros((2, 2), np.float32)
    for t in range(2):
        _assert_same(native.step(still), sync.step(still), f"step {t}")
    swarm = sync.envs[1].unwrapped.swarm
    swarm.pose[0, :2] = swarm.goal
    native.batch.pose[1, :2] = native.batch.goals[1]
    result = native.step(still)
    _assert_same(result, sync.step(still), "last step")
    assert result[2].tolist() == [False, True] and result[3].tolist() == [True, True]
    _assert_same(native.step(still), sync.step(still), "after")


def test_a_restarting_sub_env_reports_its_new_episodes_zero_powers_bit_for_bit():
    """At a next-step autoreset the restarting sub-envs ignore their actions and report the new episode's motor
    powers, +0.0 as ``SyncVectorEnv``'s fresh episode does: not -0.0, a negative action times nothing (the
    registry-wide parity test finds this too, now that it compares bytes, but only when its random actions are
    negative on a restart step)."""
    make = {"num_envs": 2, "max_episode_steps": 2}
    native = gym.make_vec(IDS[0], vectorization_mode="vector_entry_point", **make)
    sync = gym.make_vec(IDS[0], vectorization_mode="sync", wrappers=[RecordEpisodeMetrics], **make)
    _assert_same(native.reset(seed=4), sync.reset(seed=4), "reset")
    backwards = np.full((2, 2), -0.5, np.float32)
    for t in range(3):  # two steps of the episode, then the restart step
        result = native.step(backwards)
        _assert_same(result, sync.step(backwards), f"step {t}")
    assert result[4]["motor_powers"].tolist() == [[0.0, 0.0], [0.0, 0.0]]
    assert not np.signbit(result[4]["motor_powers"]).any()


def test_vector_env_refuses_use_after_close_and_bad_arguments():
    envs = gym.make_vec(IDS[0], num_envs=2)
    envs.reset(seed=0)
    envs.close()
    with pytest.raises(gym.error.ClosedEnvironmentError):
        envs.step(np.zeros((2, 2), np.float32))
    for kwargs, name in (
        ({"num_envs": 0}, "num_envs"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
        ({"render_mode": "rgb_array"}, "render_mode"),
        ({"autoreset_mode": "sometimes"}, "autoreset_mode"),
        ({"n_robots": 3}, "n_robots"),
        ({"terrain_noise": -1.0}, "terrain_noise"),
    ):
        with pytest.raises(ValueError, match=name):
            gym.make_vec(IDS[1], **{"num_envs": 2, **kwargs})
    envs = gym.make_vec(IDS[1], num_envs=2)
    envs.reset(seed=0)
    for bad in (np.zeros((3, 2)), np.full((2, 2), 1.5), np.full((2, 2), np.nan)):
        with pytest.raises(ValueError, match="actions"):
            envs.step(bad)
    with pytest.raises(ValueError, match="seed"):
        envs.reset(seed=[1, 2, 3])
