"""The Platonic Beasts paper's remaining claims (``seeds/002``): the rolling gait's straight strip (Figure 7) and its
direction, the sharp turn as the paper writes it (section 5, Figures 10 and 11) being the turn task's paper
algorithm, and the zero-tip gait (section 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from baselines.beast.gait import RollingGaitController
from baselines.beast.planner import BeastPlanner

#: The working tumble's start stance K0 (spec beast.md, appendix): limbs 1-3 stand, limb 4 points straight up.
K0 = np.radians([[0, 56.0, 115.8], [120, 56.0, 115.8], [-120, 56.0, 115.8], [0, 90, 0]]).ravel()
#: The feasibility study's straight strip (1-based tumbles).
STRIP = [(1, 2, 3, 4), (4, 2, 1, 3), (4, 3, 2, 1), (1, 3, 4, 2)]


def _planner(joint1_deg: float) -> BeastPlanner:
    return BeastPlanner(joint_ranges=np.radians([[-joint1_deg, joint1_deg], [-120, 160], [-150, 150]]))


def _strip_from_k0(planner: BeastPlanner):
    """The default controller's first tumble and its look-ahead's path from K0, and the support triangles' centroids
    rolled on paper along them, in the first tumble's frame (x: the tip's direction)."""
    feet = planner.feet(K0)
    controller = RollingGaitController(planner)
    controller.support = (0, 1, 2)
    first, _, path = controller._candidates(feet, K0)[0]
    rot, origin = planner.tumble_frame(feet, 0, 1, 2)
    ground = {limb: (rot @ (feet[limb] - origin))[:2] for limb in (0, 1, 2)}
    centroids = [np.mean(list(ground.values()), axis=0)]
    for tumble in (first, *path):
        ground = planner.roll_on_paper(ground, tumble)
        centroids.append(np.mean(list(ground.values()), axis=0))
    return [tuple(v + 1 for v in t) for t in (first, *path)], np.array(centroids)


@pytest.mark.parametrize("joint1_deg", [180.0, 250.0])
def test_the_straight_strip_runs_30_degrees_left_of_the_first_tip(joint1_deg):
    """Figure 7's straight path: the rolling gait's strip (1234)(4213)(4321)(1342) runs from foot 3 towards foot 2,
    30 degrees to the left of the first tip, each tumble advancing the support triangle by half a side (150 mm on
    the 300 mm pattern), 600 mm in four. With joint 1 within +-180 degrees it is the only strip the 4-beast can
    roll; with the turn task's +-250 the other strip phase, (1234)(1423)(3412)(3241) 30 degrees to the right, is
    plannable too, and the gait's default heading is what picks this one."""
    sequence, centroids = _strip_from_k0(_planner(joint1_deg))
    assert sequence == STRIP
    advance = centroids[-1] - centroids[0]
    assert np.linalg.norm(advance) == pytest.approx(0.600, abs=1e-3)
    assert math.degrees(math.atan2(advance[1], advance[0])) == pytest.approx(30.0, abs=0.1)
    # Every tumble moves the centroid 173 mm (two inradii) zig-zagging about the strip, 150 mm along it.
    steps = np.diff(centroids, axis=0)
    along = steps @ [math.cos(math.radians(30)), math.sin(math.radians(30))]
    np.testing.assert_allclose(along, 0.150, atol=1e-3)
    np.testing.assert_allclose(np.linalg.norm(steps, axis=1), 0.300 / math.sqrt(3), atol=1e-3)


mujoco = pytest.importorskip("mujoco")

import gymnasium as gym  # noqa: E402

import polyenvs  # noqa: E402, F401  (registers the ids)
from baselines import make_policy  # noqa: E402
from baselines.beast import RollingGait, SharpTurn  # noqa: E402


def _run(env, policy, until, steps):
    """Step ``policy`` on ``env`` (seed 0) until ``until(controller, info)`` or ``steps``: (controller, info, the
    body's position in the start stance and in the stance after each tumble)."""
    obs, _ = env.reset(seed=0)
    state, start, stances, phase = None, True, [env.unwrapped.data.qpos[:2].copy()], "start"
    for _ in range(steps):
        action, state = policy.predict(obs, state=state, episode_start=[start])
        start = False
        obs, _, _, _, info = env.step(action)
        controller = policy._controllers[int(state[0, 0])]
        if phase == "stance" != controller.phase:
            stances.append(env.unwrapped.data.qpos[:2].copy())
        phase = controller.phase
        if until(controller, info):
            break
    return controller, info, np.array(stances)


def test_the_roll_task_turns_the_start_stance_so_that_the_strip_runs_along_the_heading():
    """``BeastRoll`` puts the strip, not the first tip, along the commanded heading: in MuJoCo the first tumble
    rolls the body 30 degrees to the right of the heading, the second 30 degrees to its left, two together along it.
    Seed 0, heading 90 degrees: 61.9 and 91.8 degrees, 182 and 183 mm between stances."""
    env = gym.make("polyenvs/BeastRoll-v1", heading_deg=90.0)
    policy = RollingGait(env.observation_space, env.action_space, max_tumbles=2)
    controller, _, stances = _run(env, policy, lambda c, _: c.phase == "done", 4000)
    assert controller.history == STRIP[:2]
    directions = [math.degrees(math.atan2(d[1], d[0])) for d in (stances[1] - stances[0], stances[2] - stances[0])]
    assert directions == pytest.approx([60.0, 90.0], abs=5.0)


def test_the_turn_tasks_paper_policy_is_the_sharp_turn_as_written():
    """Section 5: "Limb 1 is held in contact while the robot rolls about it, effectively synthesizing a cone". The
    turn tasks' paper policy (``--policy paper``) is that cone (``sharp_turn_cone``), not our look-ahead steering
    (``sharp_turn``, which rolls a further tumble off the cone): every tumble keeps the limb on the inside of the
    turn planted, limb 2 for the default left turn of 60 degrees (the mirror image of the paper's limb 1), and the
    cone stops when joint 1 can wind no further, 3 tumbles and about 50 degrees in. Seed 0 on BeastTurn-v1: 49.96
    degrees, 3 tumbles."""
    for env_id in ("polyenvs/BeastTurn-v0", "polyenvs/BeastTurn-v1"):
        env = gym.make(env_id)
        policy = make_policy("paper", env_id, env.observation_space, env.action_space)
        assert isinstance(policy, SharpTurn) and policy.pivot == "inside"
    # The last one made, on BeastTurn-v1, rolls.
    controller, info, _ = _run(env, policy, lambda c, _: c.phase == "done" and c.history, 6000)
    assert controller.history == [(1, 2, 3, 4), (4, 2, 1, 3), (3, 2, 4, 1)]
    assert env.unwrapped.episode_metrics()["heading_change_deg"] == pytest.approx(50.0, abs=3.0)


def _canonical_tumble(**kwargs):
    """The canonical tumble (1234) of ``RollingGait(**kwargs)`` on BeastTumble-v1, seed 0, without the registry's
    time limit, and what touched the floor meanwhile (MuJoCo's contacts, not the robot's switches): (controller,
    episode metrics, fewest feet on the floor at once, whether anything but a foot touched it, largest normal force
    on a foot in body weights)."""
    from polyenvs.beast.tasks import BeastTumbleV1Env

    env = BeastTumbleV1Env()
    model, data = env.model, env.data
    policy = RollingGait(env.observation_space, env.action_space, max_tumbles=1, **kwargs)
    feet = [model.geom(f"limb{i}_foot").id for i in range(1, 5)]
    force = np.zeros(6)
    obs, _ = env.reset(seed=0)
    state, start, fewest, other, peak = None, True, 4, False, 0.0
    for _ in range(4000):
        action, state = policy.predict(obs, state=state, episode_start=[start])
        start = False
        obs, _, _, _, info = env.step(action)
        found = [data.sensor(f"limb{i}_foot_floor").data[0] for i in range(1, 5)]
        fewest = min(fewest, sum(n > 0 for n in found))
        other |= data.sensor("robot_floor").data[0] > sum(found)
        for j in range(data.ncon):
            if {data.contact[j].geom1, data.contact[j].geom2} & set(feet):
                mujoco.mj_contactForce(model, data, j, force)
                peak = max(peak, force[0])
        controller = policy._controllers[int(state[0, 0])]
        if controller.phase == "done":
            break
    return controller, env.episode_metrics(), fewest, other, peak / (env.params.total_mass * 9.81)


def test_the_zero_tip_tumble_keeps_three_feet_down_and_lands_softly_but_slowly():
    """Section 3: "all four limbs can simultaneously contact the ground, and thus the duration of the tip episode can
    be reduced to zero. Such a zero tip gait will be slower, but will minimize the impact loads on the limb", "at
    most one limb is off the ground at any time". The rolling gait's tip stands on two feet and lands foot 4 at 1.56
    body weights in 15.6 s; the zero-tip tumble never has fewer than three feet down, loads no foot above 0.44 body
    weights and takes 33.1 s, advancing the body 158 mm (seed 0)."""
    tipped, tipped_metrics, tipped_fewest, _, tipped_peak = _canonical_tumble()
    controller, metrics, fewest, other, peak = _canonical_tumble(zero_tip=True)
    assert tipped_fewest == 2 and tipped.history == controller.history == [(1, 2, 3, 4)]
    assert fewest == 3 and not other and metrics["success"] == 1.0
    assert peak < 0.5 * tipped_peak
    assert metrics["time_s"] > 1.5 * tipped_metrics["time_s"]
    assert metrics["distance_m"] > 0.13


def test_zero_tip_is_a_flag_of_the_four_beasts_rolling_gait():
    from polyenvs.beast.tasks import BeastRollEnv

    env = BeastRollEnv()
    with pytest.raises(ValueError, match="zero_tip"):
        RollingGait(env.observation_space, env.action_space, zero_tip=1)
    six = BeastRollEnv(polyhedron="octahedron")
    with pytest.raises(ValueError, match="zero_tip"):
        RollingGait(six.observation_space, six.action_space, zero_tip=True)
    assert RollingGait(env.observation_space, env.action_space, zero_tip=True).describe()["zero_tip"] is True
