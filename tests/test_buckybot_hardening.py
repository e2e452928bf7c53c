"""Regression tests for the defects an adversarial review found (issue 5): each failed on the code before it."""

from __future__ import annotations

import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401
from polyenvs.buckybot.env import BuckybotAction, ground_truth_parts
from polyenvs.buckybot.floor_plans import BUILTIN_PLANS
from polyenvs.buckybot.simulator import PARAMETER_RANGES

IDS = ["polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotExplore-v0", "polyenvs/BuckybotGoal-v0"]
ROOT = Path(__file__).resolve().parents[1]


def truth(info: dict) -> dict:
    """The named parts of ``info["ground_truth"]``."""
    return ground_truth_parts(info["ground_truth"])


def snapshot(env) -> dict:
    """Everything that decides what an environment does next."""
    core = env.unwrapped
    sim = core.sim
    arrays = {
        "state": sim.state,
        "walls": sim.walls,
        "normals": sim.streams.normals,
        "cursor": sim.streams.cursor,
        "observations": core._observations,
        "out": core._out,
    }
    for i, array in enumerate(core._kernel_arrays):
        arrays[f"task{i}"] = array
    snap = {name: np.array(value, copy=True) for name, value in arrays.items()}
    snap["rng"] = repr(core.np_random.bit_generator.state)
    snap["plans"] = [id(p) for p in core._slot_plans]
    return snap


def assert_unchanged(before: dict, after: dict) -> None:
    assert before.keys() == after.keys()
    for name in before:
        if isinstance(before[name], np.ndarray):
            assert np.array_equal(before[name], after[name], equal_nan=True), name
        else:
            assert before[name] == after[name], name


def test_rejected_reset_on_random_rooms_changes_nothing_and_never_crashes():
    """Defect 1: a rejected pose installed the new room first, and compiled code then indexed stale tables
    (exit 139). The issue's loop, in a fresh process so a crash fails the test instead of killing the run."""
    code = """
import gymnasium as gym, polyenvs
env = gym.make("polyenvs/BuckybotWallFollow-v0", floor_plan="random")
for seed in range(200):
    env.reset(seed=seed)
    try: env.reset(options={"pose": (1e6, 1e6, 0)})
    except ValueError: pass
    for t in range(300): env.step(t % 3 if t % 7 else 1)
print("done")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.strip() == "done", out.stderr[-2000:]


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize(
    "options",
    [
        {"pose": (1e6, 1e6, 0)},
        {"pose": (5.0, 5.0, 0.0)},
        {"pose": "here"},
        {"face": 0},
        {"bogus": 1},
        "pose",
        {"goal": (-500.0, 0.0)},
    ],
)
def test_a_rejected_reset_leaves_the_environment_exactly_as_it_was(env_id, options):
    env = gym.make(env_id, floor_plan="random")
    env.reset(seed=3)
    for action in (1, 2, 1):
        env.step(action)
    before = snapshot(env)
    with pytest.raises(ValueError):
        env.reset(seed=99, options=options)
    assert_unchanged(before, snapshot(env))
    twin = gym.make(env_id, floor_plan="random")  # never saw the failed reset: both must go on identically
    twin.reset(seed=3)
    for action in (1, 2, 1):
        twin.step(action)
    for action in (2, 2, 0, 1, 1):
        assert np.array_equal(env.step(action)[0], twin.step(action)[0])


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("action", [3, -1, 1.5, np.nan, "a", None, np.array([1, 2])])
def test_a_rejected_action_changes_nothing(env_id, action):
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    env.step(1)
    before = snapshot(env)
    with pytest.raises((ValueError, TypeError)):
        env.step(action)
    assert_unchanged(before, snapshot(env))


def test_goal_that_cannot_fit_is_refused_at_construction():
    """Defect 2: a goal radius or a room with no room for a goal crashed at reset (IndexError from np.quantile)."""
    with pytest.raises(ValueError, match="goal_radius_cm"):
        gym.make(IDS[2], goal_radius_cm=150)
    small_room = [(0, 0, 80, 0), (80, 0, 80, 80), (80, 80, 0, 80), (0, 80, 0, 0)]
    with pytest.raises(ValueError, match="goal_radius_cm=15 leaves no room"):
        gym.make(IDS[2], floor_plan=small_room)
    # The largest accepted radius works in every random room (rooms that cannot host it are redrawn).
    env = gym.make(IDS[2], floor_plan="random", goal_radius_cm=50, body_radius_cm=26)
    for seed in range(50):
        _, info = env.reset(seed=seed)
        assert np.isfinite(info["goal"]).all()


def _crossings(path: np.ndarray, segments: np.ndarray) -> int:
    """Moves (consecutive path points) that touch a wall: orientation tests, written apart from the project's code."""
    a, b = path[:-1, None, :], path[1:, None, :]
    c, d = segments[None, :, :2], segments[None, :, 2:]

    def orient(p, q, r):
        return np.sign(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    proper = (orient(a, b, c) * orient(a, b, d) <= 0) & (orient(c, d, a) * orient(c, d, b) <= 0)
    moved = np.any(path[1:] != path[:-1], axis=1)[:, None]
    return int((proper & moved).any(axis=1).sum())


def _random_parameters(rng: np.random.Generator) -> dict:
    kwargs = {}
    for name, (low, high) in PARAMETER_RANGES.items():
        pick = rng.random()
        kwargs[name] = low if pick < 0.2 else high if pick < 0.4 else float(rng.uniform(low, high))
    return kwargs


THIN_WALLS = [
    (0, 0, 400, 0), (400, 0, 400, 300), (400, 300, 0, 300), (0, 300, 0, 0),
    (200, 0, 200, 140), (200, 170, 200, 300), (60, 150, 140, 150), (300, 60, 300, 60.5),
]  # fmt: skip


def test_no_accepted_parameters_let_the_robot_through_a_wall():
    """Defect 3: only the landing point was checked, so small bodies or long steps walked through walls (with
    body_radius_cm=2 the robot was outside the room in 16,432 of 20,000 steps). Property: for random accepted
    parameter sets (a fifth of them at each end of every range), no move ever touches a wall, the centre stays
    off the walls and inside the room, and rewards and observations stay finite."""
    rng = np.random.default_rng(2026)
    plans = [*BUILTIN_PLANS, "random", THIN_WALLS]
    for trial in range(24):
        kwargs = _random_parameters(rng)
        plan = plans[trial % len(plans)]
        env = gym.make(IDS[0], floor_plan=plan, max_episode_steps=None, **kwargs).unwrapped
        obs, info = env.reset(seed=trial)
        path = [truth(info)["pose"][:2]]
        for _ in range(1500):
            action = (
                int(rng.integers(3)) if rng.random() < 0.7 else int(np.argmin(truth(info)["true_range_cm"][[0, 2, 4]]))
            )
            obs, reward, _, _, info = env.step(action)
            assert np.isfinite(reward) and np.isfinite(obs).all()
            assert truth(info)["wall_distance_cm"] > 0.0
            path.append(truth(info)["pose"][:2])
        segments = env.plan.segments
        assert _crossings(np.array(path), segments) == 0, (plan, kwargs)
        assert env.plan.in_main_region(path[-1]), (plan, kwargs)


@pytest.mark.parametrize(
    "env_id, kwargs, name",
    [
        (IDS[0], {"step_forward_cm": 1e300}, "step_forward_cm"),
        (IDS[0], {"step_forward_sd_cm": 1e300}, "step_forward_sd_cm"),
        (IDS[0], {"d_star_cm": 1e160}, "d_star_cm"),
        (IDS[0], {"x_s_cm": 1e-310}, "x_s_cm"),
        (IDS[0], {"noise_scale": True}, "noise_scale"),
        (IDS[0], {"d_star_cm": "50"}, "d_star_cm"),
        (IDS[0], {"body_radius_cm": 2.0}, "body_radius_cm"),
        (IDS[0], {"heading_sd_deg": float("inf")}, "heading_sd_deg"),
        (IDS[1], {"coverage_goal": False}, "coverage_goal"),
        (IDS[1], {"cell_cm": 1}, "cell_cm"),
        (IDS[1], {"cell_cm": 0.5}, "cell_cm"),
        (IDS[2], {"goal_distance_cm": (0, "far")}, "goal_distance_cm"),
        (IDS[2], {"goal_distance_cm": (0, 1e9)}, "goal_distance_cm"),
    ],
)
def test_implausible_values_are_refused(env_id, kwargs, name):
    """Defect 4: these gave -inf rewards or passed as numbers; every physical parameter has a documented range."""
    with pytest.raises(ValueError, match=name):
        gym.make(env_id, **kwargs)


def test_every_parameter_range_is_documented_in_the_docstring():
    doc = gym.spec(IDS[0]).entry_point
    module, name = doc.split(":")
    text = getattr(__import__(module, fromlist=[name]), name).__doc__
    for name, (low, high) in PARAMETER_RANGES.items():
        assert name in text and f"[{low:g}, {high:g}]" in text, name


def test_rewards_stay_finite_at_the_ends_of_every_range():
    for ends in (0, 1):
        kwargs = {name: bounds[ends] for name, bounds in PARAMETER_RANGES.items()}
        tasks = ({"d_star_cm": (20.0, 150.0)[ends], "x_s_cm": (1.0, 100.0)[ends]}, {}, {"goal_radius_cm": 5.0})
        for env_id, task in zip(IDS, tasks, strict=True):
            env = gym.make(env_id, **kwargs, **task)
            env.reset(seed=ends)
            env.action_space.seed(ends)
            for _ in range(300):
                obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
                assert np.isfinite(reward) and np.isfinite(obs).all()
                assert all(np.isfinite(v) for v in env.unwrapped.episode_metrics().values())
                if terminated or truncated:
                    env.reset()


@pytest.mark.parametrize(
    "env_id, kwargs, name",
    [
        (
            IDS[1],
            {
                "cell_cm": 2.0,
                "floor_plan": [(0, 0, 4000, 0), (4000, 0, 4000, 3000), (4000, 3000, 0, 3000), (0, 3000, 0, 0)],
            },
            "cell_cm",
        ),  # fmt: skip
        (
            IDS[0],
            {"floor_plan": [(0, 0, 10000, 0), (10000, 0, 10000, 10000), (10000, 10000, 0, 10000), (0, 10000, 0, 0)]},
            "floor_plan",
        ),  # fmt: skip
        (IDS[0], {"floor_plan": [(0, 0, 1e300, 0), (0, 0, 0, 10)]}, "floor_plan"),
    ],
)
def test_sizes_that_would_take_minutes_are_refused(env_id, kwargs, name):
    """Defect 5: cell_cm=1 took 12.7 s to reset, a 100 m room 29.5 s, and 1e300 coordinates crashed numpy."""
    with pytest.raises(ValueError, match=name):
        gym.make(env_id, **kwargs)


def test_the_largest_accepted_grid_builds_quickly_enough_to_be_used():
    """A 50 m room at 10 cm and the office at 2 cm are accepted (and built by compiled code)."""
    big = [(0, 0, 5000, 0), (5000, 0, 5000, 5000), (5000, 5000, 0, 5000), (0, 5000, 0, 0)]
    env = gym.make(IDS[1], floor_plan=big)
    env.reset(seed=0)
    env = gym.make(IDS[1], cell_cm=2.0)
    env.reset(seed=0)
    assert 0 < env.unwrapped.episode_metrics()["coverage"] < 1


@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_memory_stays_bounded_over_long_episodes(render_mode):
    """Defect 9: the unwrapped env kept every pose (291 MB per million steps). Now nothing grows per step."""
    env = gym.make(IDS[0], render_mode=render_mode).unwrapped
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(3, size=60_000).tolist()
    for a in actions[:5000]:
        env.step(a)
    tracemalloc.start()
    start, _ = tracemalloc.get_traced_memory()
    for a in actions:
        env.step(a)
    end, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert end - start < 100_000  # bytes, after 60,000 steps


def test_one_frame_size_per_instance_whatever_the_room():
    """Defect 10: frames took the room's shape, so AddRenderObservation left its own observation space."""
    from gymnasium.wrappers import AddRenderObservation

    env = AddRenderObservation(gym.make(IDS[0], floor_plan="random", render_mode="rgb_array"), render_only=True)
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs)
        obs, *_ = env.step(1)
        assert env.observation_space.contains(obs)


def test_clear_errors_for_render_before_reset_and_odd_options():
    """Defect 11: AttributeError, 'dictionary update sequence element', and np.float64(10.0) in messages."""
    env = gym.make(IDS[0], render_mode="rgb_array").unwrapped
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        env.render()
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        env.step(0)
    with pytest.raises(ValueError, match="options must be a dict"):
        env.reset(options="pose")
    with pytest.raises(ValueError) as error:
        gym.make(IDS[0], d_star_cm=np.float64(10.0))
    assert "got 10.0" in str(error.value) and "np.float64" not in str(error.value)


def test_actions_are_an_int_enum_and_play_has_keys(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    from gymnasium.utils.play import PlayableGame

    game_env = gym.make(IDS[0], render_mode="rgb_array")
    game_env.reset(seed=0)
    assert PlayableGame(game_env).relevant_keys == {ord("a"), ord("d"), ord("s")}
    env = gym.make(IDS[0], noise_scale=0.0)
    env.reset(seed=0, options={"pose": (200.0, 150.0, 0.0), "face": 1})
    *_, info = env.step(BuckybotAction.FORWARD_LEFT)
    assert truth(info)["pose"][1] < 150.0  # 240° in the frame: down and to the left
    *_, info = env.step(BuckybotAction.BACK)
    np.testing.assert_allclose(truth(info)["pose"][:2], [200.0, 150.0], atol=1e-9)
    keys = env.unwrapped.get_keys_to_action()
    assert sorted(keys.values()) == [0, 1, 2] and all(isinstance(k, tuple) for k in keys)


def test_compiled_kernels_never_index_out_of_bounds():
    """The environment and vector suites once more with numba's bounds checking on (a fresh cache, so every
    kernel is recompiled with the checks): an out-of-bounds index raises instead of corrupting memory."""
    env = {**os.environ, "NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": str(ROOT / ".pytest_cache" / "numba-boundscheck")}
    tests = ["tests/test_envs_shared.py", "tests/test_buckybot_envs.py", "tests/test_buckybot_vector.py"]
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *tests],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
        env=env,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
