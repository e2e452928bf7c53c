"""Hand baselines: the paper's wall follower and its failure modes, and every baseline beating random."""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest

from baselines import available_policies, make_policy
from baselines.table import BASELINES
from polyenvs.evaluation.episodes import evaluate
from polyenvs.registry import ALL_IDS, import_attribute

WALL = "polyenvs/BuckybotWallFollow-v0"


def _summary(env_id, policy, plan=None, episodes=6, **policy_kwargs):
    env_kwargs = {"floor_plan": plan} if plan else {}
    return evaluate(env_id, policy, episodes=episodes, seed=100, env_kwargs=env_kwargs, policy_kwargs=policy_kwargs)


def test_wall_follower_laps_a_rectangular_room_counter_clockwise():
    """With the paper's noise: at least one counter-clockwise lap per episode, mean |d - d*| under 10 cm."""
    doc = _summary(WALL, "paper", "rectangle")
    for episode in doc["episodes"]:
        assert episode["metrics"]["laps"] >= 1
        assert episode["metrics"]["progress_cm"] > 0  # counter-clockwise along the walls
        assert episode["metrics"]["wall_distance_error_cm"] < 10.0
        assert episode["metrics"]["blocked_tips"] == 0
    assert doc["summary"]["perimeter_fraction"] > 0.95


def test_corner_oscillation_is_observable_and_reduced_by_the_rules():
    """Paper: at 90° corners the follower alternates between faces; larger x_s and no backtracking help.

    Oscillation varies a lot between episodes (x_s = 40: 0 to 179 per episode), so the means take 20 episodes."""
    plain = _summary(WALL, "wall_follower", "corner", episodes=20)["summary"]["oscillation_events"]
    larger_xs = _summary(WALL, "wall_follower", "corner", episodes=20, x_s_cm=40.0)["summary"]["oscillation_events"]
    no_backtrack = _summary(WALL, "wall_follower", "corner", episodes=20, no_backtrack=True)["summary"][
        "oscillation_events"
    ]
    assert plain > 50  # back-and-forth tips per 500 steps
    assert larger_xs < 0.6 * plain
    assert no_backtrack < 5


def test_hallway_oscillation_is_observable_and_reduced_by_the_rules():
    """Paper: nearly equidistant from two walls the follower alternates; the clockwise exception (with the
    other rules) stops it, at the price of travelling clockwise, which the paper also warns about.

    Per episode the oscillation ranges from 1 to 171, so the means take 20 episodes (plain 76.7, the exception
    alone 65.9, all rules 1.6 when this was written)."""
    plain = _summary(WALL, "wall_follower", "hallway", episodes=20)["summary"]
    rules = _summary(WALL, "wall_follower_rules", "hallway", episodes=20)["summary"]
    exception_only = _summary(WALL, "wall_follower", "hallway", episodes=20, clockwise_exception=True)["summary"]
    assert plain["oscillation_events"] > 30
    assert exception_only["oscillation_events"] < plain["oscillation_events"]
    assert rules["oscillation_events"] < 5
    assert rules["progress_cm"] < plain["progress_cm"]


@pytest.mark.parametrize(
    "env_id, metric",
    [
        ("polyenvs/BuckybotWallFollow-v0", "perimeter_fraction"),
        ("polyenvs/BuckybotExplore-v0", "coverage"),
        ("polyenvs/BuckybotGoal-v0", "success"),
    ],
)
def test_paper_baseline_beats_random(env_id, metric):
    paper = _summary(env_id, "paper", episodes=4)["summary"]
    rand = _summary(env_id, "random", episodes=4)["summary"]
    assert paper[metric] > rand[metric] + 0.2
    assert paper["return"] > rand["return"]


def test_every_registered_policy_runs():
    for env_id in ("polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotExplore-v0", "polyenvs/BuckybotGoal-v0"):
        for name in available_policies(env_id):
            doc = evaluate(env_id, name, episodes=1, seed=0)
            assert doc["episodes"][0]["length"] > 0


def test_every_registry_id_has_its_baselines_row_and_no_other_id_has_one():
    """The table on the baselines floor is keyed by the registry's ids, all of them and in their order: a task
    without a row would have only "random", a row without a task would never run."""
    assert list(BASELINES) == ALL_IDS


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_every_baseline_factory_imports_and_the_paper_is_one_of_them(env_id):
    row = BASELINES[env_id]
    for baseline in row.baselines:
        assert callable(import_attribute(baseline.factory)), baseline
    assert row.paper in row.names
    assert available_policies(env_id) == ["random", *row.names, "paper"]


def test_predict_follows_the_sb3_convention():
    env = gym.make(WALL)
    policy = make_policy("paper", WALL, env.observation_space, env.action_space)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs)
    assert env.action_space.contains(int(action))
    batch = np.stack([obs, obs])
    actions, state = policy.predict(batch, state=None, episode_start=np.array([True, True]))
    assert actions.shape == (2,) and state.shape[0] == 2
    again, _ = policy.predict(batch, state=state, episode_start=np.array([True, True]))
    np.testing.assert_array_equal(actions, again)  # episode_start clears the memory


def test_sb3_evaluate_policy_accepts_a_baseline():
    evaluation = pytest.importorskip("stable_baselines3.common.evaluation")
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(WALL, n_envs=2, seed=0)
    policy = make_policy("paper", WALL, venv.observation_space, venv.action_space)
    mean, _ = evaluation.evaluate_policy(policy, venv, n_eval_episodes=2)
    assert mean > 0


def test_unknown_policies_and_parameters_are_clear_errors():
    with pytest.raises(ValueError, match="unknown policy"):
        evaluate(WALL, "nope", episodes=1)
    with pytest.raises(ValueError, match="bad parameters"):
        evaluate(WALL, "paper", episodes=1, policy_kwargs={"nonsense": 1})
    with pytest.raises(ValueError, match="unknown environment"):
        evaluate("polyenvs/Missing-v0", "paper", episodes=1)


@pytest.mark.parametrize(
    "space",
    [
        gym.spaces.Box(-1.0, 1.0, (12,), np.float32),  # a beast's
        gym.spaces.Box(np.array([-3.0, 0.5, -1e-3], np.float32), np.array([2.0, 7.0, 1e-3], np.float32)),
        gym.spaces.Box(-2.0, 5.0, (3, 4), np.float64),
        gym.spaces.Box(np.array([-1.0, -np.inf], np.float32), np.array([1.0, 1.0], np.float32)),  # Box.sample's
        gym.spaces.Discrete(5),  # the space's own sample
    ],
)
def test_random_policy_draws_box_samples_bit_for_bit(space):
    """RandomPolicy's shortcut for a bounded float box gives Box.sample's actions, draw for draw, and leaves the
    generator where Box.sample leaves it."""
    from baselines.base import RandomPolicy

    policy = RandomPolicy(gym.spaces.Box(-1, 1, (2,)), space, seed=1000)
    reference = copy.deepcopy(space)
    reference.seed(1000)
    for _ in range(500):
        action, _ = policy.predict(np.zeros(2, np.float32))
        expected = reference.sample()
        assert np.asarray(action).dtype == np.asarray(expected).dtype and np.shape(action) == np.shape(expected)
        assert np.array_equal(action, expected)
    assert policy.action_space.np_random.bit_generator.state == reference.np_random.bit_generator.state
