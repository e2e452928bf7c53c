"""Held-out layouts (issue 16): every registry row takes ``layouts="default" | "train" | "test"``; "default" is
the environment as it was, "train" and "test" are seeded distributions disjoint by the family's stated rule
(:mod:`polyenvs.core.layouts`), and no layout starts a body in a wall or in another body (geometry written here,
apart from the simulators). Issue 30: the training side draws every kind of feature its test side does (each
family's declared kinds), and Buckybot's training rooms, which now draw them, leave every place the robot fits
reachable."""

from __future__ import annotations

import importlib
import inspect
from collections import Counter

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from polyenvs.buckybot import floor_plans
from polyenvs.buckybot.floor_plans import BUILTIN_PLANS, LAYOUT_SPLIT, TEST_PLANS
from polyenvs.buckybot.geometry import BODY_RADIUS_CM
from polyenvs.bumper import maps
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.layouts import LayoutSplit, SplitParameter
from polyenvs.registry import REGISTRY
from polyenvs.swarm import corridor_v0, formation_v0, obstacle_field_v0
from polyenvs.swarm import layouts as swarm_layouts

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


# --- kinds of feature: what the test side holds, training draws (issue 30) -----------------------------------------

#: The module that declares each family's kinds (``LAYOUT_KINDS``) and finds them (``episode_kinds``); the beasts'
#: layouts are physical parameters, with no kinds of feature.
KIND_MODULES = {"buckybot": floor_plans, "bumper": maps, "swarm": swarm_layouts}
KIND_SEEDS = 60
#: A kind of the test side that training draws in fewer of its episodes than this is not one it teaches.
MIN_TRAINING_SHARE = 0.05


def _kind_rows():
    return [pytest.param(row, id=row.id) for row in ROWS if row.family in KIND_MODULES]


@pytest.mark.parametrize("row", _kind_rows())
def test_training_draws_every_kind_its_test_side_draws(row):
    """Over 60 seeds of each side, every kind of feature the test side draws is among the family's declared kinds
    and in at least 5 % of the training episodes: a held-out layout is new in its split parameter, not in what
    an agent meets there."""
    module = KIND_MODULES[row.family]
    declared = {kind.name for kind in module.LAYOUT_KINDS}
    drawn = {}
    for layouts in ("train", "test"):
        env = _make(row, layouts=layouts)
        drawn[layouts] = Counter()
        for seed in range(KIND_SEEDS):
            env.reset(seed=seed)
            drawn[layouts].update(module.episode_kinds(_core(env)))
        env.close()
    assert set(drawn["train"]) | set(drawn["test"]) <= declared
    rare = {kind: drawn["train"][kind] / KIND_SEEDS for kind in drawn["test"]}
    assert all(share >= MIN_TRAINING_SHARE for share in rare.values()), (rare, drawn["test"])


def test_the_kind_finders_tell_the_features_the_issue_names():
    """Buckybot's hand-drawn test plans each show the kind the issue names (45° and slanted walls, a partition with
    two sides to follow, notches, pillars); the cart's maps a 45° wall and boxes; a swarm's obstacle is in the way
    when a robot driving straight to the goal would touch it, and by a wall when a robot cannot pass between them."""
    expected = {
        "t_room": {"notch"},
        "octagon": {"45° wall"},
        "two_rooms": {"partition"},
        "u_room": {"notch"},
        "pillared_hall": {"pillar"},
        "trapezoid": {"slanted wall"},
    }
    assert {name: set(floor_plans.plan_kinds(FloorPlan(walls))) for name, walls in TEST_PLANS.items()} == expected
    assert floor_plans.plan_kinds(FloorPlan(BUILTIN_PLANS["rectangle"])) == frozenset()
    cart = {name: set(maps.map_kinds(maps.make_map(name))) for name in ("paper", "rectangle", "obstacles")}
    assert cart == {"paper": {"45° wall"}, "rectangle": set(), "obstacles": {"45° wall", "box"}}

    def swarm_kinds(circle):  # a 10 x 6 m field, one robot of radius 0.14 m going from (1, 3) to (9, 3)
        walls = swarm_layouts.box_walls(0.0, 0.0, 10.0, 6.0)
        return set(swarm_layouts.layout_kinds(walls, np.array([circle]), [[1.0, 3.0]], [9.0, 3.0], 0.14))

    assert swarm_kinds([5.0, 3.3, 0.2]) == {"obstacle in the way"}  # 0.3 m off the way: the robot's rim touches it
    assert swarm_kinds([5.0, 3.4, 0.2]) == set()
    assert swarm_kinds([5.0, 0.45, 0.2]) == {"obstacle by a wall"}  # 0.25 m from the wall: narrower than a robot
    assert swarm_kinds([5.0, 0.5, 0.2]) == set()


def _walls_cross(segments: np.ndarray) -> bool:
    """Whether two walls cross (each passes strictly through the other; walls meeting at an end do not)."""
    a, b = segments[:, None, 0:2], segments[:, None, 2:4]
    c, d = segments[None, :, 0:2], segments[None, :, 2:4]

    def side(p, q, r):
        return np.sign(
            (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        )

    return bool(((side(a, b, c) * side(a, b, d) < 0) & (side(c, d, a) * side(c, d, b) < 0)).any())


def _grow(cells: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The ``free`` cells 8-connected to ``cells`` (by repeated one-cell growth)."""
    while True:
        padded = np.pad(cells, 1)
        grown = free & np.any(
            [np.roll(np.roll(padded, dy, 0), dx, 1)[1:-1, 1:-1] for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0
        )
        if (grown == cells).all():
            return cells
        cells = grown


def _robot_space(walls: np.ndarray, radius: float, cell: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """Grid points (``cell`` apart over the walls' box and a margin) and which of them a robot of ``radius`` fits on
    inside the walls: clear of every wall by ``radius``, and not reachable from the grid's rim (outside)."""
    xs = np.arange(walls[:, [0, 2]].min() - 2 * cell, walls[:, [0, 2]].max() + 2 * cell, cell)
    ys = np.arange(walls[:, [1, 3]].min() - 2 * cell, walls[:, [1, 3]].max() + 2 * cell, cell)
    points = np.stack(np.meshgrid(xs, ys), axis=-1)
    free = (_segment_distance(points.reshape(-1, 2), walls).min(axis=1) >= radius).reshape(points.shape[:2])
    rim = np.zeros_like(free)
    rim[[0, -1], :] = rim[:, [0, -1]] = True
    return points, free & ~_grow(rim & free, free)


def _pieces(inside: np.ndarray) -> int:
    """How many 8-connected pieces ``inside`` falls into."""
    count, left = 0, inside.copy()
    while left.any():
        seed = np.zeros_like(left)
        seed[np.unravel_index(np.argmax(left), left.shape)] = True
        left &= ~_grow(seed, left)
        count += 1
    return count


def _wall_groups(segments: np.ndarray) -> np.ndarray:
    """A label per wall: walls joined end to end (at a shared end) share one."""
    ends = np.round(segments.reshape(-1, 2, 2), 3)
    shared = (np.abs(ends[:, None, :, None, :] - ends[None, :, None, :, :]).max(-1) == 0).any(axis=(2, 3))
    labels = np.arange(len(segments))
    while True:
        joined = np.where(shared, labels[None, :], len(segments)).min(axis=1)
        if (joined == labels).all():
            return labels
        labels = joined


def _wall_distances(segments: np.ndarray) -> np.ndarray:
    """``(S, S)`` distance between walls that do not cross: the least from an end of one to the other."""
    ends = segments.reshape(-1, 2)
    to_walls = _segment_distance(ends, segments).reshape(len(segments), 2, len(segments)).min(axis=1)
    return np.minimum(to_walls, to_walls.T)


def _outline(walls: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Which walls are the room's outline: those joined to the westmost wall."""
    return groups == groups[walls[:, [0, 2]].min(axis=1).argmin()]


def _narrowest_passage(walls: np.ndarray, groups: np.ndarray) -> float:
    """The narrowest way between a pillar or a partition (any wall off the outline) and a wall of another group; a
    partition's foot on the south wall is no way."""
    outline = _outline(walls, groups)
    apart = _wall_distances(walls) + np.where(groups[:, None] == groups[None, :], np.inf, 0.0)
    south = outline & (walls[:, [1, 3]].max(axis=1) == 0.0)
    feet = (apart < 1e-6) & south[None, :]
    return float(np.where(feet, np.inf, apart)[~outline].min(initial=np.inf))


def _pillars(walls: np.ndarray, groups: np.ndarray) -> list[np.ndarray]:
    """The corners of each pillar: a group of walls off the outline, joined end to end (a partition is one wall)."""
    outline = _outline(walls, groups)
    return [walls[groups == g].reshape(-1, 2) for g in set(groups[~outline]) if (groups == g).sum() > 1]


def _room_space(walls: np.ndarray, groups: np.ndarray, radius: float) -> np.ndarray:
    """Which points of :func:`_robot_space`'s grid a robot of ``radius`` fits on inside the outline and outside
    every pillar."""
    points, inside = _robot_space(walls, radius)
    for corners in _pillars(walls, groups):
        inside &= ~((points >= corners.min(axis=0)) & (points <= corners.max(axis=0))).all(axis=-1)
    return inside


def test_buckybot_training_rooms_are_sound_for_the_robot():
    """Over 200 training rooms (geometry written here): each is in the training interval of the width rule, fits
    the frame and the wall tables, has no walls crossing, keeps every pillar and partition ``PASSAGE_CM`` (less
    the 1 mm rounding) from every other wall but the south wall a partition may stand on, has every pillar in the
    room, and leaves the space a robot fits in one piece: every start and goal spot is reachable, every pillar and partition can be gone round."""
    rng = np.random.default_rng(30)
    for draw in range(200):
        walls = floor_plans.layout_plan(rng, "train").segments
        assert LAYOUT_SPLIT.classify({"room width": np.ptp(walls[:, [0, 2]])}) == "train", draw
        assert len(walls) <= floor_plans.MAX_RANDOM_SEGMENTS and walls.min() >= 0.0, draw
        assert walls[:, [0, 2]].max() <= 700.0 and walls[:, [1, 3]].max() <= 550.0, draw
        assert not _walls_cross(walls), draw
        groups = _wall_groups(walls)
        assert _narrowest_passage(walls, groups) >= floor_plans.PASSAGE_CM - 0.2, draw
        assert all(
            _enclosed(corners.mean(axis=0), walls[_outline(walls, groups)]) for corners in _pillars(walls, groups)
        )
        assert _pieces(_room_space(walls, groups, BODY_RADIUS_CM + 2.0)) == 1, draw


@pytest.mark.parametrize("layouts", ["train", "test"])
def test_buckybot_goal_is_reachable_from_the_start(layouts):
    """In every Goal episode of 40 seeds the robot can drive from its start to the goal (a path clear of every wall
    by the body radius, on a 5 cm grid)."""
    env = gym.make("polyenvs/BuckybotGoal-v0", layouts=layouts).unwrapped
    for seed in range(40):
        env.reset(seed=seed)
        points, inside = _robot_space(np.asarray(env.plan.segments), env.body_radius_cm)
        nearest = [
            np.unravel_index(np.hypot(*(points - p).transpose(2, 0, 1)).argmin(), inside.shape)
            for p in (env.position, env.goal)
        ]
        start = np.zeros_like(inside)
        start[nearest[0]] = True
        assert _grow(start & inside, inside)[nearest[1]], (seed, env.plan.name)
