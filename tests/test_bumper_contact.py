"""A bump credits the wall the bumper touched (issue 29, finding 1).

The paper's robot logs a bump when its bumper's switch closes, at the end of the drive stage; backing up after it
can touch another wall with the cart's rear, which no switch senses. BumperCartExplore-v0 and -v1 let that
back-up contact overwrite the bump's: the touched-wall reward, the coverage and ``info["contact_point"]`` named a
wall the bumper never touched (0.1-0.35% of bumps). BumperCartExplore-v2 credits the bump's own contact; v0 and
v1 keep theirs, so that their results reproduce.

The geometry here is written apart from the simulator (plain numpy on the map's polygons and the cart's
documented dimensions, nothing from ``polyenvs.bumper.cart`` or the map's packed walls): the body is the rectangle
from ``rear_cm`` behind the axle to the bumper, its front edge, ``bumper_offset_cm`` ahead and ``bumper_width_cm``
wide, at ``info["pose_at_bump"]``; walls are cut into equal cells of at most ``cell_cm``, polygon by polygon, edge
by edge.

Where no wall corner juts into the room the bump's contact is on the bumper. Round a box's corner it may be on the
body's side: on the slight arc of the unmatched motors the inner side sweeps past where the bumper went, and the
cart stops where it touches (0.22% of bumps on ``obstacles``, 0.03% on the test layouts; none on the paper's arena).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)

EXPLORE_V2 = "polyenvs/BumperCartExplore-v2"
#: How far (cm) a contact point may lie off the bumper and off a wall: the drive stops 1e-6 cm short, and rounding.
TOL_CM = 1e-4
#: The cart's documented defaults: the bumper 7 cm ahead of the axle, 3 inches wide, the body 5 cm behind the
#: axle; cells of 5 cm.
BUMPER_OFFSET_CM, BUMPER_WIDTH_CM, REAR_CM, CELL_CM = 7.0, 3.0 * 2.54, 5.0, 5.0


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Distance from ``p`` to segment ``ab`` and the fraction along it of the nearest point."""
    e = b - a
    along = float(np.clip(np.dot(p - a, e) / np.dot(e, e), 0.0, 1.0))
    return float(np.hypot(*(p - a - along * e))), along


def _body(pose_deg: np.ndarray) -> np.ndarray:
    """The body's corners at ``(x_cm, y_cm, heading_deg)``, round the rectangle: front right, front left (the
    bumper between them), rear left, rear right."""
    heading = math.radians(pose_deg[2])
    forward, left = np.array([math.cos(heading), math.sin(heading)]), np.array([-math.sin(heading), math.cos(heading)])
    half = 0.5 * BUMPER_WIDTH_CM
    local = [(BUMPER_OFFSET_CM, -half), (BUMPER_OFFSET_CM, half), (-REAR_CM, half), (-REAR_CM, -half)]
    return np.array([pose_deg[:2] + ahead * forward + aside * left for ahead, aside in local])


def _distance_to_body(point: np.ndarray, pose_deg: np.ndarray, bumper_only: bool) -> float:
    """Distance from ``point`` to the bumper, or to the body's outline."""
    corners = _body(pose_deg)
    edges = [(corners[0], corners[1])]
    if not bumper_only:
        edges += [(corners[i], corners[(i + 1) % 4]) for i in (1, 2, 3)]
    return min(_point_segment_distance(point, a, b)[0] for a, b in edges)


def _wall_cells_at(point: np.ndarray, polygons) -> set[int]:
    """The wall cells within ``TOL_CM`` of ``point`` (two at a cell boundary or a corner), numbered over the walls
    in order: polygon by polygon, edge by edge, each edge cut into ``ceil(length / CELL_CM)`` equal cells."""
    cells, first = set(), 0
    for polygon in polygons:
        vertices = np.asarray(polygon, dtype=np.float64)
        for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
            length = float(np.hypot(*(b - a)))
            count = max(1, math.ceil(length / CELL_CM - 1e-9))
            distance, along = _point_segment_distance(point, a, b)
            if distance <= TOL_CM:
                slack = TOL_CM / length
                for position in (along - slack, along + slack):
                    cells.add(first + min(max(int(position * count), 0), count - 1))
            first += count
    return cells


def _check_bumps(env_id: str, seeds, bumper_only: bool = True, **kwargs) -> int:
    """Every bump of uniformly random turns: the contact point on the bumper (or, with ``bumper_only`` false, the
    body) and on a wall of the map's polygons, and the cell the episode credits one of that point's cells. Returns
    the number of bumps checked."""
    env = gym.make(env_id, **kwargs)
    raw = env.unwrapped
    bumps = 0
    for seed in seeds:
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        truncated = False
        while not truncated:
            before = raw._touched[0].copy()
            _, _, _, truncated, info = env.step(rng.uniform(-1.0, 1.0, 1))
            if not info["bumped"]:
                assert np.array_equal(raw._touched[0], before)
                continue
            bumps += 1
            point = info["contact_point"]
            where = f"seed {seed}, cycle {raw._cycles[0]:g}: contact {point}, pose at bump {info['pose_at_bump']}"
            assert _distance_to_body(point, info["pose_at_bump"], bumper_only) <= TOL_CM, where
            cells = _wall_cells_at(point, raw.world.polygons)
            assert cells, where
            fresh = set(np.flatnonzero(raw._touched[0] > before).tolist())
            assert fresh <= cells and (fresh or cells & set(np.flatnonzero(before).tolist())), where
    return bumps


def test_every_bump_credits_a_cell_under_the_bumper():
    """The issue's rate (0.1-0.35% of bumps) makes 3,000 bumps meet several back-up contacts."""
    assert _check_bumps(EXPLORE_V2, range(60)) > 2500


def test_every_bump_credits_a_cell_under_the_bumper_round_a_corner_that_juts_in():
    assert _check_bumps(EXPLORE_V2, range(20), map="l_room") > 800


@pytest.mark.parametrize("kwargs", [{"map": "obstacles"}, {"layouts": "test"}])
def test_every_bump_credits_a_cell_the_cart_touched_among_boxes(kwargs):
    """Boxes in the room and held-out rooms: walls on every side of the cart when it backs up."""
    assert _check_bumps(EXPLORE_V2, range(20), bumper_only=False, **kwargs) > 800


def _issue_example(env_id: str, **kwargs) -> dict:
    """The issue's example: seed 0, 83 cycles of ``default_rng(0).uniform(-1, 1, 1)``; the last cycle's info."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(83):
        info = env.step(rng.uniform(-1.0, 1.0, 1))[4]
    return info


def test_the_issues_bump_credits_the_x_120_wall():
    """The bumper's front right corner is on the x = 120 wall; the back-up then touched the y = 0 wall."""
    info = _issue_example(EXPLORE_V2, budget_cycles=83, max_episode_steps=83)
    right = _body(info["pose_at_bump"])[0]
    assert info["bumped"] and right[0] == pytest.approx(120.0, abs=TOL_CM)
    np.testing.assert_allclose(info["contact_point"], right, atol=TOL_CM)


@pytest.mark.parametrize(
    "env_id,kwargs",
    [
        ("polyenvs/BumperCartExplore-v0", {}),
        ("polyenvs/BumperCartExplore-v1", {"budget_cycles": 83, "max_episode_steps": 83}),
    ],
)
def test_v0_and_v1_keep_crediting_the_back_ups_contact(env_id, kwargs):
    """Their results reproduce: the issue's cycle still names the rear corner on the y = 0 wall."""
    info = _issue_example(env_id, **kwargs)
    np.testing.assert_allclose(info["contact_point"], [104.299244, 0.0], atol=1e-5)
