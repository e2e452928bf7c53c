"""The beasts' native vector env (polyenvs/beast/vector.py): bit for bit ``gym.make`` through autoresets, on any
number of threads; a bad batch of actions changes nothing."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from gymnasium.vector import AutoresetMode  # noqa: E402

from polyenvs.beast.env import BeastEnv  # noqa: E402
from polyenvs.core.episode_metrics import RecordEpisodeMetrics  # noqa: E402
from polyenvs.registry import REGISTRY  # noqa: E402
from tests.vector_helpers import assert_same  # noqa: E402

BEAST_IDS = [row.id for row in REGISTRY if row.kind == "gymnasium" and row.family == "beast"]


def _pair(env_id, mode=AutoresetMode.NEXT_STEP, num_envs=3, max_episode_steps=20, threads=2, **kwargs):
    """The native vector env and ``SyncVectorEnv`` over ``gym.make(id)`` (the time limit's metrics added, as the
    native env reports them on every row that ends)."""
    make = {"num_envs": num_envs, "max_episode_steps": max_episode_steps, **kwargs}
    native = gym.make_vec(env_id, vectorization_mode="vector_entry_point", autoreset_mode=mode, threads=threads, **make)
    sync = gym.make_vec(
        env_id,
        vectorization_mode="sync",
        vector_kwargs={"autoreset_mode": mode},
        wrappers=[RecordEpisodeMetrics],
        **make,
    )
    return native, sync


def _run_side_by_side(native, sync, steps, policy=None, seed=11) -> int:
    """Both on the same actions (random, or ``policy(observations)``), bit for bit; the episodes that ended."""
    observations, _ = native.reset(seed=seed)
    assert_same((observations, _), sync.reset(seed=seed), "reset")
    native.action_space.seed(0)
    ended = 0
    for t in range(steps):
        actions = native.action_space.sample() if policy is None else policy(observations)
        result = native.step(actions)
        assert_same(result, sync.step(actions), f"step {t}")
        observations = result[0]
        ended += int((result[2] | result[3]).sum())
    return ended


@pytest.mark.parametrize("layouts", ["default", "test"])
@pytest.mark.parametrize("env_id", BEAST_IDS)
def test_each_sub_env_is_gym_make_with_seed_s_plus_i_through_autoresets(env_id, layouts):
    native, sync = _pair(env_id, layouts=layouts)
    assert type(native).__name__.endswith("VectorEnv") and native.threads == 2
    assert _run_side_by_side(native, sync, 45) == 6  # every row's episode truncated twice
    assert_same(native.reset(seed=[3, None, 5]), sync.reset(seed=[3, None, 5]), "list reset")


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_terminations_restart_like_gym_make_in_both_autoreset_modes(mode):
    """BeastRecover holding its pose from seed 0 stands still after 53 steps (terminated); the other row runs into
    the time limit: the rows restart, with the metrics of the episodes they ended, as gym.make's do."""
    native, sync = _pair("polyenvs/BeastRecover-v1", mode, num_envs=2, max_episode_steps=80)
    hold = native.observation_structure["prev_action"]
    terminated = []
    native.step = _spy(native.step, terminated)
    assert _run_side_by_side(native, sync, 120, policy=lambda obs: obs[:, hold], seed=0) >= 2
    assert any(row[0] for row in terminated)


def _spy(step, terminated: list):
    def spied(actions):
        result = step(actions)
        terminated.append(result[2].copy())
        return result

    return spied


def test_the_threads_change_nothing_and_are_checked():
    runs = []
    for threads in (1, 3, 7):
        envs = gym.make_vec(
            "polyenvs/BeastRoll-v1", num_envs=4, vectorization_mode="vector_entry_point", threads=threads
        )
        envs.reset(seed=5)
        envs.action_space.seed(1)
        runs.append(tuple(envs.step(envs.action_space.sample()) for _ in range(15)))
    assert_same(runs[0], runs[1])
    assert_same(runs[0], runs[2])
    for bad in (0, -1, 1025, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads"):
            gym.make_vec("polyenvs/BeastRoll-v1", num_envs=2, vectorization_mode="vector_entry_point", threads=bad)


def _state(envs):
    """Everything a step changes: each sub-env's MuJoCo state and packed rows."""
    inner = envs.unwrapped
    mujoco_state = [np.concatenate([env.data.qpos, env.data.qvel, env.data.ctrl]) for env in inner._envs]
    return (*mujoco_state, *(array.copy() for array in inner._rows), inner._steps.copy())


def test_a_bad_batch_of_actions_changes_no_sub_env():
    envs = gym.make_vec("polyenvs/BeastTumble-v1", num_envs=3, vectorization_mode="vector_entry_point", threads=2)
    twin = gym.make_vec("polyenvs/BeastTumble-v1", num_envs=3, vectorization_mode="vector_entry_point", threads=2)
    for e in (envs, twin):
        e.reset(seed=2)
        e.action_space.seed(2)
        e.step(e.action_space.sample())
    before = _state(envs)
    good = envs.action_space.sample()
    for row, value in ((2, np.nan), (1, 1.5), (0, -np.inf)):
        bad = good.copy()
        bad[row, 4] = value  # the rows before it are valid: a partial step would move them
        with pytest.raises(ValueError, match="actions"):
            envs.step(bad)
        assert_same(_state(envs), before)
    with pytest.raises(ValueError, match="actions"):
        envs.step(good[:2])
    assert_same(_state(envs), before)
    assert_same(envs.step(good), twin.step(good))


class _PythonTask(BeastEnv):
    """A task whose rules are Python (the adding guide's kind)."""

    reward_names = ("still",)
    metric_names = ("spin_sq",)

    def _task_reset(self, feet_mask):
        self._metrics = {"spin_sq": 0.0}

    def _task_step(self, summary):
        self._metrics["spin_sq"] = summary.spin_sq
        return (-summary.spin_sq,), False


def test_a_python_task_says_it_has_no_native_vector_env():
    with pytest.raises(ValueError, match="_task_step"):
        _PythonTask.VectorEnv(num_envs=2)
