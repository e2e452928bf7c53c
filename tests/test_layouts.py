"""Held-out layouts (issue 16): every registry row takes ``layouts="default" | "train" | "test"``; "default" is
the environment as it was, "train" and "test" are seeded distributions disjoint by the family's stated rule
(:mod:`polyenvs.core.layouts`), and no layout starts a body in a wall or in another body (geometry written here,
apart from the simulators)."""

from __future__ import annotations

import importlib
import inspect

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.buckybot.floor_plans import BUILTIN_PLANS, LAYOUT_SPLIT, TEST_PLANS
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.layouts import LayoutSplit, SplitParameter
from polyenvs.registry import REGISTRY
from polyenvs.swarm import corridor_v0, formation_v0, obstacle_field_v0

ROWS = list(REGISTRY)
#: Resets per layouts value (the beasts build a MuJoCo model per instance, not per reset: a few are enough).
SEEDS = {"beast": 3}


def _make(row, **kwargs):
    if row.kind == "gymnasium":
        return gym.make(row.id, **kwargs)
    return importlib.import_module(row.id).parallel_env(**kwargs)


def _core(env):
    return env.unwrapped if hasattr(env, "unwrapped") and not hasattr(env, "possible_agents") else env


def _rollout(env, seed: int, steps: int = 15) -> list:
    """Observations of a reset and ``steps`` seeded random actions (every agent's, for a swarm)."""
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    if hasattr(env, "possible_agents"):
        for i, agent in enumerate(env.possible_agents):
            env.action_space(agent).seed(i)
        for _ in range(steps):
            if not env.agents:
                break
            trace.append(env.step({a: env.action_space(a).sample() for a in env.agents})[0])
        return [np.concatenate([o[a] for a in sorted(o)]) if o else np.zeros(0) for o in trace]
    env.action_space.seed(0)
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        trace.append(obs)
        if terminated or truncated:
            break
    return trace


def _layouts(row, layouts: str) -> list[dict]:
    env = _make(row, layouts=layouts)
    drawn = []
    for seed in range(SEEDS.get(row.family, 12)):
        env.reset(seed=seed)
        drawn.append(_core(env).episode_layout())
    env.close()
    return drawn


@pytest.mark.parametrize("row", ROWS, ids=lambda r: r.id)
def test_every_row_takes_layouts_documented_and_checked(row):
    """The keyword is documented in the env's Arguments (from its split declaration) and a bad value raises
    ValueError naming it."""
    env = _make(row)
    doc = inspect.getdoc(type(_core(env)))
    assert '| layouts | "default" |' in doc, doc[-1500:]
    env.close()
    for bad in ("held_out", ["test"], 1, None):
        with pytest.raises(ValueError, match="layouts"):
            _make(row, layouts=bad)


@pytest.mark.parametrize("row", ROWS, ids=lambda r: r.id)
def test_default_layouts_is_the_environment_as_it_was(row):
    """layouts="default" gives the episodes of no keyword at all, bit for bit."""
    for seed in (0, 5):
        plain, default = _rollout(_make(row), seed), _rollout(_make(row, layouts="default"), seed)
        assert len(plain) == len(default)
        for a, b in zip(plain, default, strict=True):
            assert np.array_equal(a, b)


@pytest.mark.parametrize("row", ROWS, ids=lambda r: r.id)
def test_train_and_test_layouts_are_randomised_and_disjoint_by_the_stated_rule(row):
    """Every train layout is classified "train" and every test layout "test" by the family's split (disjoint
    intervals of the split parameters); no default layout is a test layout; both distributions vary from seed to
    seed and differ from each other."""
    split = _core(_make(row)).layout_split
    train, test, default = (_layouts(row, layouts) for layouts in ("train", "test", "default"))
    assert [split.classify(v) for v in train] == ["train"] * len(train)
    assert [split.classify(v) for v in test] == ["test"] * len(test)
    assert "test" not in [split.classify(v) for v in default]

    def key(values):
        return tuple(np.round(np.atleast_1d(v), 9).tolist().__repr__() for v in values.values())

    assert len({key(v) for v in train}) > 1 and len({key(v) for v in test}) > 1
    assert not {key(v) for v in train} & {key(v) for v in test}


@pytest.mark.parametrize("row", [r for r in ROWS if r.family != "beast"], ids=lambda r: r.id)
def test_same_seed_same_layout_and_episode(row):
    """A test layout is drawn from the seeded generator: the same seed gives the same layout and episode, even
    after other episodes in the same instance."""
    fresh, used = _make(row, layouts="test"), _make(row, layouts="test")
    _rollout(used, 99)
    first, again = _rollout(fresh, 4), _rollout(used, 4)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert repr(_core(fresh).episode_layout()) == repr(_core(used).episode_layout())


def test_a_split_with_overlapping_intervals_is_refused():
    with pytest.raises(ValueError, match="overlap"):
        SplitParameter("width", "cm", train=(1.0, 2.0), test=(2.0, 3.0))
    split = LayoutSplit((SplitParameter("width", "cm", train=(1.0, 2.0), test=(3.0, 4.0)),), varies="rooms")
    assert [split.classify({"width": w}) for w in (1.5, 3.5, 2.5, [1.5, 3.5])] == ["train", "test", None, None]


def test_buckybot_test_plans_are_test_layouts_and_no_built_in_plan_is():
    """The hand-drawn plans are all on the test side of the width rule, fit the frame and wall tables random rooms
    use, and none of them (nor any built-in, the defaults among them) equals another plan of the other side."""
    for name, walls in TEST_PLANS.items():
        plan = FloorPlan(walls, name=name)
        assert LAYOUT_SPLIT.classify({"room width": np.ptp(plan.segments[:, [0, 2]])}) == "test", name
        assert len(walls) <= 24 and plan.segments.min() >= 0.0
        assert plan.segments[:, [0, 2]].max() <= 700.0 and plan.segments[:, [1, 3]].max() <= 550.0
    builtins = {repr(np.round(FloorPlan(w).segments, 6).tolist()) for w in BUILTIN_PLANS.values()}
    tests = {repr(np.round(FloorPlan(w).segments, 6).tolist()) for w in TEST_PLANS.values()}
    assert not builtins & tests


def test_layouts_refuse_a_map_they_would_ignore():
    """ "train" and "test" draw their own plans, rooms and obstacles: another floor plan, map or obstacle count is
    refused by name, not silently dropped."""
    for make in (
        lambda: gym.make("polyenvs/BuckybotWallFollow-v0", layouts="train", floor_plan="office"),
        lambda: gym.make("polyenvs/BumperCartExplore-v0", layouts="test", map="maze"),
        lambda: obstacle_field_v0.parallel_env(layouts="test", n_obstacles=9),
        lambda: formation_v0.parallel_env(layouts="train", n_obstacles=2),
    ):
        with pytest.raises(ValueError, match="layouts"):
            make()
    gym.make("polyenvs/BuckybotExplore-v0", layouts="test", floor_plan="office")  # its own default: accepted


# --- physically honest starts (geometry written here) ---------------------------------------------------------


def _segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """``(P, S)`` distance from each point to each segment ``(x1, y1, x2, y2)``."""
    a, b = segments[None, :, 0:2], segments[None, :, 2:4]
    p = points[:, None, :]
    t = np.clip(((p - a) * (b - a)).sum(-1) / ((b - a) ** 2).sum(-1), 0.0, 1.0)
    return np.hypot(*(a + t[..., None] * (b - a) - p).transpose(2, 0, 1))


def _enclosed(point: np.ndarray, segments: np.ndarray) -> bool:
    """Whether rays from ``point`` along +x, -x, +y and -y each meet a wall (the point is inside some room)."""
    for direction in ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)):
        d = np.array(direction)
        a, e = segments[:, 0:2], segments[:, 2:4] - segments[:, 0:2]
        denom = d[0] * e[:, 1] - d[1] * e[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((a[:, 0] - point[0]) * e[:, 1] - (a[:, 1] - point[1]) * e[:, 0]) / denom
            u = ((a[:, 0] - point[0]) * d[1] - (a[:, 1] - point[1]) * d[0]) / denom
        if not ((t > 0) & (u >= 0) & (u <= 1)).any():
            return False
    return True


@pytest.mark.parametrize("layouts", ["train", "test"])
@pytest.mark.parametrize("env_id", ["polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotGoal-v0"])
def test_buckybot_layouts_start_clear_of_every_wall_inside_the_room(env_id, layouts):
    env = gym.make(env_id, layouts=layouts).unwrapped
    for seed in range(40):
        env.reset(seed=seed)
        walls = np.asarray(env.plan.segments)
        points = [env.position] + ([env.goal] if hasattr(env, "goal") else [])
        for point in points:
            assert _segment_distance(point[None], walls).min() >= env.body_radius_cm, (seed, env.plan.name, point)
            assert _enclosed(point, walls), (seed, env.plan.name, point)


@pytest.mark.parametrize("layouts", ["train", "test"])
@pytest.mark.parametrize("module", [corridor_v0, obstacle_field_v0, formation_v0], ids=lambda m: m.__name__)
def test_swarm_layouts_start_no_robot_or_obstacle_in_a_wall_or_in_each_other(module, layouts):
    env = module.parallel_env(layouts=layouts)
    radius = env.platform.radius_m
    walls = np.asarray(env.layout.walls, dtype=np.float64)
    for seed in range(30):
        env.reset(seed=seed)
        robots, circles = env.pose[:, :2], env.circles
        gap = np.hypot(*(robots[:, None] - robots[None]).transpose(2, 0, 1)) + 3 * radius * np.eye(len(robots))
        assert gap.min() > 2 * radius, seed
        assert _segment_distance(robots, walls).min() > radius, seed
        centres = np.hypot(*(robots[:, None] - circles[None, :, :2]).transpose(2, 0, 1))
        assert (centres > circles[None, :, 2] + radius).all(), seed
        assert (_segment_distance(circles[:, :2], walls) > circles[:, 2:3]).all(), seed
        apart = np.hypot(*(circles[:, None, :2] - circles[None, :, :2]).transpose(2, 0, 1))
        assert (apart + 10 * np.eye(len(circles)) > circles[:, None, 2] + circles[None, :, 2]).all(), seed
        assert _enclosed(env.goal, walls)
