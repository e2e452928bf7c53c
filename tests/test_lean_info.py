"""The lean ``info`` of issue 33: the task's metrics only on the step that ends an episode, a method that returns them
at any time, a wrapper that adds them where Gymnasium's ``TimeLimit`` truncates, a native vector env that puts them
on the rows that ended, and consumers that keep what they read."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import polyenvs
from polyenvs.core.episode_metrics import RecordEpisodeMetrics
from polyenvs.evaluation.episodes import make_agent
from polyenvs.evaluation.rollout import run_episode
from polyenvs.registry import REGISTRY

ENV_IDS = polyenvs.ENV_IDS
VECTOR_IDS = [row.id for row in REGISTRY if getattr(row, "native_vector", False)]
RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
#: Short episodes: the time limit ends every one of them within a few steps.
LIMIT = 6


def _random_steps(env, seed: int, steps: int):
    """``(terminated, truncated, info)`` of ``steps`` random steps from a reset seeded ``seed``, resetting at each end;
    the reset infos first, as ``(False, False, info)``."""
    _, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    yield False, False, info
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        yield terminated, truncated, info
        if terminated or truncated:
            _, info = env.reset()
            yield False, False, info


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_metrics_are_in_the_info_of_an_end_only_and_the_method_has_them_always(env_id):
    """No reset's or middle step's info has ``episode_metrics``; a terminated step's has them, equal to
    ``env.unwrapped.episode_metrics()``, which returns the same names at every step (the episode so far)."""
    env = gym.make(env_id, max_episode_steps=LIMIT)
    with pytest.raises(ResetNeeded):
        env.unwrapped.episode_metrics()
    names = None
    for terminated, truncated, info in _random_steps(env, seed=3, steps=3 * LIMIT):
        metrics = env.unwrapped.episode_metrics()
        names = names or set(metrics)
        assert set(metrics) == names and all(type(v) is float for v in metrics.values())
        if not (terminated or truncated):
            assert "episode_metrics" not in info
        elif terminated or "episode_metrics" in info:
            assert info["episode_metrics"] == metrics
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_wrapper_puts_the_metrics_on_time_limit_truncations(env_id):
    """Under ``RecordEpisodeMetrics`` every end has the metrics, the time limit's too, and they are the method's,
    which keeps them after the end until the next reset."""
    env = RecordEpisodeMetrics(gym.make(env_id, max_episode_steps=LIMIT))
    ends = 0
    for terminated, truncated, info in _random_steps(env, seed=5, steps=2 * LIMIT):
        if terminated or truncated:
            assert info["episode_metrics"] == env.unwrapped.episode_metrics()
            ends += 1
        else:
            assert "episode_metrics" not in info
    assert ends >= 2
    env.close()


def test_the_wrapper_adds_nothing_to_the_envs_own_ends_and_refuses_envs_without_metrics():
    """A budget the env truncates at itself (BumperCartExplore-v1's ``budget_cycles``) reports the metrics without
    the wrapper; an env without ``episode_metrics()`` is refused by name."""
    env = gym.make("polyenvs/BumperCartExplore-v1", budget_cycles=3)  # under the registered limit of 50
    env.reset(seed=0)
    for budget_left in (2, 1, 0):
        _, _, _, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        assert truncated == (budget_left == 0) == ("episode_metrics" in info)
    assert info["episode_metrics"] == env.unwrapped.episode_metrics()
    with pytest.raises(ValueError, match="env must have an episode_metrics"):
        RecordEpisodeMetrics(gym.make("CartPole-v1"))


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_the_native_vector_env_reports_the_metrics_on_the_rows_that_ended(env_id):
    """The native env applies the time limit itself: ``episode_metrics`` is on exactly the rows that terminated or
    truncated this step (``_episode_metrics``), with the values ``SyncVectorEnv`` over ``RecordEpisodeMetrics(
    gym.make(id))`` gives, and absent from the info of a step where no row ended."""
    make = {"num_envs": 4, "max_episode_steps": 25}
    native = gym.make_vec(env_id, vectorization_mode="vector_entry_point", **make)
    sync = gym.make_vec(env_id, vectorization_mode="sync", wrappers=[RecordEpisodeMetrics], **make)
    assert "episode_metrics" not in native.reset(seed=7)[1]
    sync.reset(seed=7)
    native.action_space.seed(0)
    ends = set()
    for _ in range(60):
        actions = native.action_space.sample()
        _, _, terminated, truncated, info = native.step(actions)
        expected = sync.step(actions)[4]
        done = terminated | truncated
        if not done.any():
            assert "episode_metrics" not in info
            continue
        ends.add(int(done.sum()))
        assert np.array_equal(info["_episode_metrics"], done)
        for name, values in expected["episode_metrics"].items():
            assert np.array_equal(info["episode_metrics"][name], values), name
    assert ends  # the time limit at least
    if "Localize" in env_id:  # random turns localize at different cycles: some steps end some rows only
        assert min(ends) < make["num_envs"]
    native.close()
    sync.close()


def _committed_random_results() -> list[Path]:
    ids = [env_id for env_id in VECTOR_IDS if "Buckybot" in env_id or "BumperCart" in env_id]
    paths = [RESULTS / f"{env_id.replace('/', '__')}__random.json" for env_id in ids]
    return [path for path in paths if path.is_file()]


@pytest.mark.parametrize("path", _committed_random_results(), ids=lambda p: p.stem)
def test_the_last_infos_metrics_are_the_committed_reference_values(path):
    """The metrics of the ending step's info (through the wrapper, time limits included) and of ``run_episode`` are
    the committed reference results' first episode, bit for bit: the lean info moved them and changed none."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    expected = doc["episodes"][0]
    env = RecordEpisodeMetrics(gym.make(doc["env_id"], **doc["env_kwargs"]))
    agent = make_agent(doc["policy"], doc["env_id"], env, seed=doc["seeds"][0])
    obs, info = env.reset(seed=expected["seed"])
    state, start, done = None, True, False
    while not done:
        action, state = agent.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        start, done = False, terminated or truncated
    assert info["episode_metrics"] == expected["metrics"]
    agent = make_agent(doc["policy"], doc["env_id"], env, seed=doc["seeds"][0])
    assert run_episode(gym.make(doc["env_id"], **doc["env_kwargs"]), agent, expected["seed"]) == expected


def test_ground_truth_is_fresh_in_a_single_env_and_a_read_only_view_in_the_vector_env():
    """A single env's ground truth is a new array each step (Gymnasium's checker refuses an info sharing memory with
    an earlier one); the vector env's is one read-only view of the state, which a consumer cannot write."""
    env = gym.make("polyenvs/BuckybotGoal-v0")
    _, first = env.reset(seed=0)
    _, _, _, _, second = env.step(1)
    assert not np.shares_memory(first["ground_truth"], second["ground_truth"])
    vector = gym.make_vec("polyenvs/BuckybotGoal-v0", num_envs=2, vectorization_mode="vector_entry_point")
    _, info = vector.reset(seed=0)
    truth = info["ground_truth"]
    assert vector.step(np.array([1, 2]))[4]["ground_truth"] is truth
    with pytest.raises(ValueError, match="read-only"):
        truth[0, 0] = 1.0


def test_the_training_adapter_keeps_a_copy_of_the_ground_truth():
    """The SB3 adapter hands each row's info over as its own arrays: a kept info stays what it was after the native
    env steps on (the ground truth is a view of its state)."""
    from polyenvs.training.vec_adapter import NativeVecEnvAdapter, make_native_vector_env

    adapter = NativeVecEnvAdapter(make_native_vector_env("polyenvs/BuckybotGoal-v0", 2), info_keys=["ground_truth"])
    adapter.seed(0)
    adapter.reset()
    kept = adapter.step(np.array([1, 2]))[3]
    before = [info["ground_truth"].copy() for info in kept]
    adapter.step(np.array([2, 1]))
    for info, truth in zip(kept, before, strict=True):
        assert np.array_equal(info["ground_truth"], truth)
    adapter.close()


def test_training_on_dummy_vec_env_sees_the_metrics_of_time_limited_episodes():
    """``polyenvs train``'s DummyVecEnv path wraps each copy in ``RecordEpisodeMetrics``: the episode-metrics
    callback reads them on time-limit truncations as on the native env."""
    from polyenvs.training.vec_adapter import make_training_vec_env

    venv = make_training_vec_env(
        "polyenvs/BuckybotWallFollow-v0", 2, seed=0, env_kwargs={"max_episode_steps": 3}, vec_env="dummy"
    )
    venv.reset()
    for _ in range(3):
        _, _, dones, infos = venv.step(np.array([1, 2]))
    assert dones.all() and all(info["TimeLimit.truncated"] and info["episode_metrics"] for info in infos)
    venv.close()
