"""The 6-beast's quadruped crawl with a broken limb on top (paper section 5): geometry, and walking in MuJoCo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from baselines.beast import Crawl
from baselines.beast.crawl import CrawlConfig, CrawlController, centre_of_mass, crawl_frame, crawl_stance_qpos
from baselines.beast.planner import BeastPlanner
from polyenvs.beast import kinematics as K

DIRS = K.limb_directions("octahedron")


@pytest.fixture(scope="module")
def planner():
    return BeastPlanner("octahedron")


def _env(limb: int):
    from polyenvs.beast.tasks import BeastRollEnv

    return BeastRollEnv(polyhedron="octahedron", disabled_limbs=(limb,))


def _floor_geoms(env) -> set:
    import mujoco

    m, d = env.unwrapped.model, env.unwrapped.data
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    return {
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, c.geom2 if c.geom1 == floor else c.geom1)
        for c in d.contact[: d.ncon]
        if floor in (c.geom1, c.geom2)
    }


@pytest.mark.parametrize("limb", range(6))
def test_crawl_frame_puts_the_broken_limb_up_and_forward_between_two_legs(limb):
    forward, left, up = crawl_frame(limb)
    np.testing.assert_allclose(up, DIRS[limb], atol=1e-12)
    np.testing.assert_allclose(np.stack([forward, left, up]) @ np.stack([forward, left, up]).T, np.eye(3), atol=1e-12)
    legs = [i for i in range(6) if abs(DIRS[i] @ up) < 0.5]
    # An X stance: every leg 45 degrees off the forward direction.
    np.testing.assert_allclose(np.abs(DIRS[legs] @ forward), math.sqrt(0.5), atol=1e-12)
    turned = crawl_frame(limb, math.pi / 2)
    np.testing.assert_allclose(turned[0], left, atol=1e-12)


@pytest.mark.parametrize("limb", [1, 4, 6])
def test_stance_qpos_has_four_feet_on_the_floor_and_the_broken_limb_straight_up(planner, limb):
    cfg = CrawlConfig()
    qpos = crawl_stance_qpos(limb, cfg, planner=planner)
    assert qpos[2] == cfg.height
    quat = qpos[3:7]
    w, x, y, z = quat
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    np.testing.assert_allclose(rot @ DIRS[limb - 1], [0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(rot @ crawl_frame(limb - 1)[0], [1, 0, 0], atol=1e-9)
    feet = planner.feet(qpos[7:]) @ rot.T + qpos[:3]
    legs = [i for i in range(6) if abs(DIRS[i] @ DIRS[limb - 1]) < 0.5]
    np.testing.assert_allclose(feet[legs, 2], planner.foot_radius, atol=1e-9)
    np.testing.assert_allclose(np.hypot(feet[legs, 0], feet[legs, 1]), cfg.reach, atol=1e-9)
    others = [i for i in range(6) if i not in legs]
    assert np.all(feet[others, 2] > qpos[2])  # the broken limb and the folded one: feet above the body centre


def test_centre_of_mass_of_the_symmetric_pose_is_the_body_centre(planner):
    np.testing.assert_allclose(centre_of_mass(planner, np.tile([0.0, math.pi / 2, 0.0], 6)), 0.0, atol=1e-12)
    # One limb straight out along +x: 0.45 kg of the 5.7 kg, its mass centre well out along x.
    q = np.tile([0.0, math.pi / 2, 0.0], 6)
    q[3:6] = [0.0, -math.pi / 2, 0.0]  # limb 2 (-x) folded back onto its axis, towards the body
    assert centre_of_mass(planner, q)[0] > 0.005


@pytest.mark.parametrize("limb", [1, 5])
def test_stance_holds_still_then_the_crawl_walks_along_x_on_its_feet(limb):
    env = _env(limb)
    policy = Crawl(env.observation_space, env.action_space, disabled_limbs=(limb,))
    obs, _ = env.reset(seed=0, options={"qpos": crawl_stance_qpos(limb)})
    data = env.unwrapped.data
    start = data.qpos[:3].copy()
    state, first = None, True
    touched, info = set(), {}
    for step in range(2500):  # 25 s
        action, state = policy.predict(obs, state=state, episode_start=np.array([first]))
        first = False
        obs, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated) and not info["sim_unstable"]
        touched |= _floor_geoms(env)
        if step == 49:  # 0.5 s holding the start pose: a resting state, no drift
            assert np.linalg.norm(data.qpos[:3] - start) < 0.003
        tilt = 2 * math.acos(min(1.0, abs(float(data.qpos[3:7] @ _up_quat(limb)))))
        assert tilt < math.radians(12)  # stays upright: the broken limb keeps pointing up
    # Only feet touch the floor, and never the broken limb's foot or its folded opposite's.
    opposite = int(np.argmin(DIRS @ DIRS[limb - 1])) + 1
    assert touched and all(name.endswith("_foot") for name in touched), touched
    assert f"limb{limb}_foot" not in touched and f"limb{opposite}_foot" not in touched
    controller = next(iter(policy._controllers.values()))
    assert isinstance(controller, CrawlController) and controller.steps >= 4 and controller.failures == 0
    # At least 0.13 m along +x in 25 s (the rolling gait from this start: a few centimetres in 60 s), nearly
    # straight.
    assert env.unwrapped.episode_metrics()["distance_m"] > 0.13
    assert abs(data.qpos[1] - start[1]) < 0.04


def _up_quat(limb: int) -> np.ndarray:
    """The start orientation's quaternion (the crawl keeps the body level and facing +x)."""
    return crawl_stance_qpos(limb)[3:7]


def test_crawl_arguments_are_validated():
    from polyenvs.beast.tasks import BeastRollEnv

    env = BeastRollEnv(polyhedron="octahedron", disabled_limbs=(2,))
    spaces = (env.observation_space, env.action_space)
    policy = Crawl(*spaces, disabled_limbs=(2,), heading_deg=30.0, rate_deg_s=25.0)
    assert policy.describe()["name"] == "crawl" and policy.describe()["disabled_limbs"] == [2]
    cases = [
        ({"disabled_limbs": ()}, "disabled_limbs"),
        ({"disabled_limbs": (1, 2)}, "disabled_limbs"),
        ({"disabled_limbs": (7,)}, "disabled_limbs"),
        ({"disabled_limbs": 3}, "disabled_limbs"),
        ({"disabled_limbs": "3"}, "disabled_limbs"),
        ({"rate_deg_s": 0.0}, "rate_deg_s"),
        ({"rate_deg_s": float("nan")}, "rate_deg_s"),
        ({"heading_deg": 270.0}, "heading_deg"),
        ({"stride": -0.1}, "stride"),
        ({"margin": 0.5}, "margin"),
        ({"max_cycles": 0}, "max_cycles"),
        ({"max_cycles": 1.5}, "max_cycles"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError, match=name):
            Crawl(*spaces, **kwargs)
    four = _four_beast_spaces()
    with pytest.raises(ValueError, match="6-beast"):
        Crawl(*four, disabled_limbs=(1,))


def _four_beast_spaces():
    from polyenvs.beast.tasks import BeastRollEnv

    env = BeastRollEnv()
    return env.observation_space, env.action_space


def test_heading_turns_the_direction_of_travel_about_the_broken_limb():
    # The stance faces +x; heading_deg=90 walks the same stance along +y, with no turn of the body.
    env = _env(3)
    policy = Crawl(env.observation_space, env.action_space, disabled_limbs=(3,), heading_deg=90.0)
    obs, _ = env.reset(seed=1, options={"qpos": crawl_stance_qpos(3)})
    start = env.unwrapped.data.qpos[:2].copy()
    state, first = None, True
    for _ in range(1800):  # 18 s
        action, state = policy.predict(obs, state=state, episode_start=np.array([first]))
        first = False
        obs, _, _, truncated, info = env.step(action)
        assert not truncated
    moved = env.unwrapped.data.qpos[:2] - start
    assert moved[1] > 0.09 and abs(moved[0]) < 0.03, moved


def _broken_limb_up_deg(data, limb: int) -> float:
    import mujoco

    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, data.qpos[3:7])
    return math.degrees(math.acos(float(np.clip((rot.reshape(3, 3) @ DIRS[limb - 1])[2], -1.0, 1.0))))


def test_from_the_task_start_the_beast_reorients_with_the_broken_limb_on_top_and_crawls_along_x():
    # Limb 1 is free (up) in the task's three-foot rolling stance: a partial roll puts it on top within 30 s, with
    # only feet ever on the floor, then the crawl walks along the task's heading (+x).
    from baselines.beast import Crawl
    from baselines.beast.crawl import ReorientController

    env = _env(1)
    policy = Crawl(env.observation_space, env.action_space, disabled_limbs=(1,))
    obs, _ = env.reset(seed=0)
    data = env.unwrapped.data
    start = data.qpos[:3].copy()
    state, first, touched, info = None, True, set(), {}
    for _ in range(4200):  # 42 s
        action, state = policy.predict(obs, state=state, episode_start=np.array([first]))
        first = False
        obs, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated) and not info["sim_unstable"]
        touched |= _floor_geoms(env)
    controller = next(iter(policy._controllers.values()))
    assert isinstance(controller, ReorientController) and controller.failure is None
    assert controller.reoriented_at is not None and controller.reoriented_at < 30.0
    assert _broken_limb_up_deg(data, 1) < 5.0
    contact = obs[env.unwrapped.observation_structure["foot_contact"]] > 0.5
    assert not contact[0] and not contact[1]  # the broken limb and its folded opposite are off the floor
    assert contact[2:].sum() >= 3  # the four legs stand (one may be swinging)
    assert touched and all(name.endswith("_foot") for name in touched), touched
    assert controller.crawl.steps >= 2 and controller.crawl.failures == 0
    assert data.qpos[0] - start[0] > 0.05 and env.unwrapped.episode_metrics()["distance_m"] > 0.05


def test_a_broken_limb_in_the_start_support_is_not_reoriented_and_the_robot_holds():
    from baselines.beast import Crawl

    env = _env(2)
    policy = Crawl(env.observation_space, env.action_space, disabled_limbs=(2,))
    obs, _ = env.reset(seed=0)
    start = env.unwrapped.data.qpos[:3].copy()
    state, first = None, True
    for _ in range(150):
        action, state = policy.predict(obs, state=state, episode_start=np.array([first]))
        first = False
        obs, *_ = env.step(action)
    controller = next(iter(policy._controllers.values()))
    assert controller.phase == "failed" and "stands in the support [2, 4, 6]" in controller.failure
    assert np.linalg.norm(env.unwrapped.data.qpos[:3] - start) < 0.005
