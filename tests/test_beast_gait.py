"""The beasts' rolling gait: planning geometry, trajectories, and the closed-loop tumble in MuJoCo."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium import spaces

from baselines.beast.gait import RollingGaitController
from baselines.beast.geometry import rotation_exp, rotation_log
from baselines.beast.observation import n_limbs_of, split_observation
from baselines.beast.planner import TUCKED, BeastPlanner, JointTrajectory
from polyenvs.beast import kinematics as K

DEG = math.pi / 180
#: The working tumble's K0 and K1 joint angles (spec beast.md, appendix), limbs 1-4, degrees.
K0 = np.array([[0, 56.0, 115.8], [120, 56.0, 115.8], [-120, 56.0, 115.8], [0, 90, 0]])
K1 = np.array([[-17.2, 15.9, 139.9], [105.2, 15.1, 141.7], [-120.8, 143.8, 27.8], [-123.3, 150.5, 43.5]])


@pytest.fixture(scope="module")
def planner():
    return BeastPlanner()


def test_stance_angles_are_the_working_tumbles_k0(planner):
    angles = planner.stance_angles((0, 1, 2))
    for limb in range(3):
        np.testing.assert_allclose(angles[limb] / DEG, K0[limb], atol=0.1)


def test_nominal_stance_feet_form_the_300_mm_triangle_under_the_body(planner):
    feet, centre = planner.nominal_feet(0, 1, 2)
    sides = [np.linalg.norm(feet[i] - feet[j]) for i, j in ((0, 1), (1, 2), (2, 0))]
    np.testing.assert_allclose(sides, 0.300, atol=1e-9)
    # The stance's up axis is limb 4's: every foot is 168 - 18 mm below the centre along it.
    np.testing.assert_allclose(feet @ K.limb_directions()[3], -(0.168 - 0.018), atol=1e-9)
    np.testing.assert_allclose(centre[:2], [-0.3 / (2 * math.sqrt(3)), 0.0], atol=1e-12)


def test_tip_plan_reaches_the_working_tumbles_k1_from_k0(planner):
    traj = planner.tip_plan((K0 * DEG).ravel(), (0, 1, 2, 3))
    assert traj is not None
    np.testing.assert_allclose(traj.q[0], (K0 * DEG).ravel(), atol=1e-9)
    # Within 0.5 degrees of the feasibility study's keyframe (its numbers are rounded to 0.1 degree and 0.1 mm).
    np.testing.assert_allclose(traj.q[-1].reshape(4, 3) / DEG, K1, atol=0.5)


def test_tip_plan_keeps_planted_feet_fixed_on_the_ground(planner):
    q0 = (K0 * DEG).ravel()
    traj = planner.tip_plan(q0, (0, 1, 2, 3))
    feet0 = planner.feet(q0)
    rot0, origin = planner.tumble_frame(feet0, 0, 1, 2)
    body0 = -rot0 @ origin
    ground0 = feet0 @ rot0.T + body0
    # Recover the body pose at every knot from the planted feet and check they never moved in the ground frame.
    for q in traj.q:
        feet = planner.feet(q)
        rot, org = planner.tumble_frame(feet, 0, 1, 2)
        np.testing.assert_allclose(feet[:3] @ rot.T - rot @ org, ground0[:3] - body0 + body0, atol=1e-9)


def test_a_planner_reuses_a_motion_only_for_exactly_the_same_inputs():
    planner = BeastPlanner()
    q0 = (K0 * DEG).ravel()
    first = planner.tip_plan(q0, (0, 1, 2, 3))
    assert planner.tip_plan(q0.copy(), (0, 1, 2, 3)) is first  # the same plan, not planned again
    with pytest.raises(ValueError):
        first.q[0, 0] = 1.0  # so that no caller can change a plan another will reuse
    # Anything the motion reads makes another motion: the angles (by one ulp), the knots, the branch rule.
    moved = q0.copy()
    moved[0] = np.nextafter(moved[0], 1.0)
    other = planner.tip_plan(moved, (0, 1, 2, 3))
    assert other is not first and not np.array_equal(other.q, first.q)
    feet = planner.feet(q0)
    rot0, origin = planner.tumble_frame(feet, 0, 1, 2)
    feet_t = (feet - origin) @ rot0.T
    pose0, pose1 = (rot0, -rot0 @ origin), (rot0, -rot0 @ origin + [0.001, 0.0, 0.0])
    args = (q0, [0, 1, 2], feet_t, pose0, pose1, {3: TUCKED})
    eight, sixteen = planner.body_motion(*args, knots=8), planner.body_motion(*args, knots=16)
    assert len(eight.times) == 9 and len(sixteen.times) == 17
    nearest = planner.body_motion(*args, knots=8, any_branch=True)
    assert nearest is not eight and planner.body_motion(*args, knots=8) is eight


def test_knot_velocities_are_the_jacobian_solution_and_the_path_is_continuous(planner):
    traj = planner.tip_plan((K0 * DEG).ravel(), (0, 1, 2, 3))
    # Finite differences of the piecewise cubic agree with its knot velocities (C1 at interior knots).
    for i in range(1, len(traj.times) - 1):
        t, h = traj.times[i], 1e-6
        np.testing.assert_allclose((traj(t + h) - traj(t - h)) / (2 * h), traj.qd[i], atol=1e-4)
    # Planted limbs: J qd = d(foot in limb frame)/dt; check it through finite differences of the foot positions.
    t = 0.5 * (traj.times[5] + traj.times[6])
    dq = (traj(t + 1e-5) - traj(t - 1e-5)) / 2e-5
    q = traj(t).reshape(4, 3)
    jac = K.limb_jacobian(q[:3])
    foot_rate = np.einsum("lij,lj->li", jac, dq.reshape(4, 3)[:3])
    fd = K.forward_kinematics(traj(t + 1e-5).reshape(4, 3)[:3]) - K.forward_kinematics(traj(t - 1e-5).reshape(4, 3)[:3])
    np.testing.assert_allclose(foot_rate, fd / 2e-5, atol=1e-6)
    # No jump anywhere: at 10 ms ticks every joint moves less than 1 degree.
    ticks = np.arange(0.0, traj.duration + 0.01, 0.01)
    path = np.stack([traj(t) for t in ticks])
    assert np.abs(np.diff(path, axis=0)).max() < 1.0 * DEG


def test_trajectory_respects_the_joint_rate(planner):
    traj = planner.tip_plan((K0 * DEG).ravel(), (0, 1, 2, 3))
    ticks = np.arange(0.0, traj.duration, 0.002)
    path = np.stack([traj(t) for t in ticks])
    rate = np.abs(np.diff(path, axis=0)).max() / 0.002
    assert rate < 1.6 * planner.rate  # a cubic between rate-limited knots peaks at most 1.5x its mean


def test_ik_near_stays_on_the_knee_branch_and_continuous(planner):
    rng = np.random.default_rng(0)
    q = np.array([[0.3, 1.0, 2.0]])
    for _ in range(200):
        step = q + rng.normal(0, 0.02, q.shape)
        step[:, 2] = np.abs(step[:, 2])
        target = K.forward_kinematics(step)
        new = planner.ik_near(target, q)
        np.testing.assert_allclose(K.forward_kinematics(new), target, atol=1e-9)
        assert new[0, 2] > 0
        assert np.abs(new - q).max() < 0.2
        q = new


def test_rotation_log_inverts_exp():
    rng = np.random.default_rng(1)
    for _ in range(50):
        w = rng.normal(size=3)
        w *= rng.uniform(0, 3.0) / np.linalg.norm(w)
        np.testing.assert_allclose(rotation_log(rotation_exp(w)), w, atol=1e-9)


def test_hermite_trajectory_hits_knots_and_holds_the_end():
    traj = JointTrajectory(np.array([0.0, 1.0, 3.0]), np.array([[0.0], [1.0], [0.0]]), np.array([[0.0], [0.5], [0.0]]))
    assert traj(1.0)[0] == pytest.approx(1.0)
    assert traj(10.0)[0] == 0.0 and traj(-1.0)[0] == 0.0
    assert traj.duration == 3.0


def test_four_tumbles_plannable_in_sequence_only_with_theta1_in_range(planner):
    # Of the 12 tumbles, those plannable from the nominal stance of their own support (theta1 within +-180 degrees
    # for the tip and the stance after it) are the feasibility study's 8.
    plannable = []
    for t in K.tumbles(4):
        l1, l2, l3, l4 = (int(v) - 1 for v in t)
        q = np.tile(TUCKED, (4, 1))
        for limb, angles in planner.stance_angles((l1, l2, l3)).items():
            q[limb] = angles
        if planner.tip_plan(q.ravel(), (l1, l2, l3, l4)) is not None:
            plannable.append("".join(str(int(v)) for v in t))
    assert plannable == ["1234", "1342", "2143", "2431", "3124", "3412", "4213", "4321"]


def test_observation_split_and_sizes():
    assert [n_limbs_of(n) for n in (52, 65, 54, 67, 72, 87, 92, 107)] == [4, 4, 4, 4, 6, 6, 8, 8]
    with pytest.raises(ValueError):
        n_limbs_of(50)
    obs = np.arange(52, dtype=np.float32)
    parts = split_observation(obs)
    assert parts["foot_contact"].tolist() == [36.0, 37.0, 38.0, 39.0]
    assert parts["prev_action"].shape == (12,) and "command" not in parts
    parts = split_observation(np.arange(67, dtype=np.float32))  # privileged, with a command
    assert parts["body_angvel"].tolist() == [62.0, 63.0, 64.0] and parts["command"].tolist() == [65.0, 66.0]


def _spaces(n_limbs=4, command=0):
    """A beast's spaces: encoder bounds the default joint limits, everything else unbounded."""
    nj = 3 * n_limbs
    low = np.full(10 * n_limbs + 12 + command, -np.inf, dtype=np.float32)
    high = -low
    low[:nj] = np.tile(np.radians([-180.0, -120.0, -150.0]), n_limbs)
    high[:nj] = np.tile(np.radians([180.0, 160.0, 150.0]), n_limbs)
    return spaces.Box(low, high, dtype=np.float32), spaces.Box(-1.0, 1.0, shape=(nj,), dtype=np.float32)


def test_policies_validate_their_arguments():
    from baselines.beast import Righting, RollingGait, SharpTurn

    obs_space, act_space = _spaces()
    for kwargs in ({"rate_deg_s": 0.0}, {"rate_deg_s": True}, {"rate_deg_s": float("nan")}, {"max_tumbles": 0}):
        with pytest.raises(ValueError, match=next(iter(kwargs))):
            RollingGait(obs_space, act_space, **kwargs)
    with pytest.raises(ValueError, match="pivot"):
        SharpTurn(*_spaces(command=2), pivot=5)
    with pytest.raises(ValueError, match="command"):
        SharpTurn(obs_space, act_space)  # nothing says which way to turn
    with pytest.raises(ValueError, match="roll_after"):
        Righting(obs_space, act_space, roll_after=1)
    with pytest.raises(ValueError, match="disabled_limbs"):
        RollingGait(obs_space, act_space, disabled_limbs=(5,))
    with pytest.raises(ValueError, match="disabled_limbs"):
        RollingGait(obs_space, act_space, disabled_limbs="1")
    with pytest.raises(ValueError, match="cube"):
        RollingGait(*_spaces(8))
    Righting(*_spaces(8))  # the righting routine stands any beast up
    unbounded = spaces.Box(-np.inf, np.inf, shape=(52,), dtype=np.float32)
    with pytest.raises(ValueError, match="joint limits"):
        RollingGait(unbounded, act_space)
    with pytest.raises(ValueError, match="action_space"):
        RollingGait(obs_space, spaces.Box(-1, 1, shape=(18,)))


def test_policy_keeps_one_plan_per_environment_and_drops_it_on_restart():
    from baselines.beast import RollingGait

    obs_space, act_space = _spaces()
    policy = RollingGait(obs_space, act_space)
    obs = np.zeros((2, 52), dtype=np.float32)
    obs[:, :12] = (K0 * DEG).ravel()
    obs[:, 36:39] = 1.0  # feet 1, 2, 3 down
    actions, state = policy.predict(obs, episode_start=np.array([True, True]))
    assert actions.shape == (2, 12) and np.all(np.abs(actions) <= 1)
    assert len(set(state[:, 0])) == 2 and len(policy._controllers) == 2
    _, state2 = policy.predict(obs, state=state, episode_start=np.array([False, True]))
    assert state2[0, 0] == state[0, 0] and state2[1, 0] != state[1, 0]
    assert len(policy._controllers) == 2


# ------------------------------------------------------------------------------------------------ MuJoCo
mujoco = pytest.importorskip("mujoco")


def _tumble_env(**kwargs):
    from polyenvs.beast.tasks import BeastTumbleEnv

    return BeastTumbleEnv(**kwargs)


@pytest.mark.parametrize("seed", [0, 1])
def test_canonical_tumble_succeeds_closed_loop(seed):
    env = _tumble_env()
    obs, _ = env.reset(seed=seed)
    controller = RollingGaitController(BeastPlanner(), max_tumbles=1)
    start = env.data.qpos[:2].copy()
    for _ in range(2000):
        obs, _, terminated, _, info = env.step(controller(obs))
        if controller.phase == "done":
            break
    assert controller.history == [(1, 2, 3, 4)]
    assert env.unwrapped.episode_metrics()["success"] == 1.0
    contact = obs[env.observation_structure["foot_contact"]]
    assert contact.tolist() == [1.0, 1.0, 0.0, 1.0]  # limbs 1, 4, 2 down, 3 free
    advance = env.data.qpos[:2] - start
    assert 0.13 < advance[0] < 0.19 and abs(advance[1]) < 0.03  # along +x, the feasibility study's ~155 mm


def test_joint_one_winds_by_a_third_of_a_turn_per_tumble_and_the_look_ahead_keeps_it_in_range():
    wide = BeastPlanner(joint_ranges=np.radians([[-250, 250], [-120, 160], [-150, 150]]))
    *moves, landed = wide.sweeps()[((0, 1, 2, 3), 0)]  # landing on the nominal stance's solution
    (d1, low1, _), (d2, _, high2), _ = moves
    assert np.degrees([d1, d2]) == pytest.approx([120.0, -120.0], abs=1.0)  # the appendix: limb 1 0 -> 120, 2 120 -> 0
    assert np.degrees(low1) == pytest.approx(-17.2, abs=1.0) and high2 == pytest.approx(0.0, abs=1e-6)
    assert np.degrees(landed) == pytest.approx(-120.0, abs=1.0)  # limb 4 lands at K3's -120...
    assert np.degrees(wide.sweeps()[((0, 1, 2, 3), 1)][-1]) == pytest.approx(60.0, abs=1.0)  # ...or flipped, at 60
    start = {0: 0.0, 1: math.radians(120), 2: math.radians(-120)}
    (after, *_) = wide.wind_on_paper(start, (0, 1, 2, 3))
    assert np.degrees([after[0], after[1], after[3]]) == pytest.approx([120.0, 0.0, -120.0], abs=1.0)
    # Limb 1 planted through a second and a third tumble about it: 240 degrees fits +-250, 360 does not.
    twice = wide.wind_on_paper({0: math.radians(120), 1: 0.0, 3: math.radians(-120)}, (0, 3, 1, 2))
    assert twice and all(math.degrees(w[0]) == pytest.approx(240.0, abs=1.0) for w in twice)
    assert not wide.wind_on_paper({0: math.radians(240), 3: 0.0, 2: 0.0}, (0, 2, 3, 1))
    strip = BeastPlanner()  # +-180: the second tumble about limb 1 is already out of range
    assert not strip.wind_on_paper({0: math.radians(120), 1: 0.0, 3: math.radians(-120)}, (0, 3, 1, 2))


@pytest.mark.parametrize("turn_deg", [60.0, -60.0])
def test_four_beast_sharp_turn_follows_the_commanded_turn(turn_deg):
    """A limb kept planted through a third tumble rolls the strip by 60 degrees about it (the paper's Figures 10
    and 11); with joint 1 limited to +-180 degrees the same policy can only roll along its strip."""
    from baselines.beast import SharpTurn
    from polyenvs.beast.tasks import BeastTurnEnv

    env = BeastTurnEnv(turn_deg=turn_deg)
    policy = SharpTurn(env.observation_space, env.action_space)
    assert np.degrees(policy.planner.joint_ranges[0]).round(3).tolist() == [-250.0, 250.0]
    obs, _ = env.reset(seed=0)
    state, start = None, True
    for _ in range(8000):
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]))
        obs, _, _, truncated, info = env.step(action)
        start = False
        if env.unwrapped.episode_metrics()["tumbles"] >= 4:
            break
    metrics = env.unwrapped.episode_metrics()
    assert (
        metrics["tumbles"] == 4 and metrics["heading_error_deg"] < 5.0
    )  # seeds 0, 1: 61.4-61.7 and -60.0 to -60.3 degrees
    controller = next(iter(policy._controllers.values()))
    if turn_deg > 0:
        assert controller.history[:3] == [(1, 2, 3, 4), (4, 2, 1, 3), (3, 2, 4, 1)]  # limb 2 planted thrice
    strip_only = BeastPlanner(joint_ranges=np.radians([[-180, 180], [-120, 160], [-150, 150]]))
    assert len(strip_only.plannable()) == 8 and len(policy.planner.plannable()) == 12


def test_six_beast_tumbles_are_all_plannable_and_disabled_limbs_never_land():
    planner = BeastPlanner("octahedron")
    plannable = planner.plannable()
    assert len(plannable) == 24  # 8 support faces x 3 edges, on the "centred" stance branch
    for _, _, l3, l4 in plannable:
        assert planner.dirs[l3] @ planner.dirs[l4] == pytest.approx(-1.0)  # the limb opposite the lifted one lands
    q = np.tile(TUCKED, (6, 1))
    for limb, angles in planner.stance_angles((1, 3, 5)).items():
        q[limb] = angles
    feet = planner.feet(q.ravel())
    for disabled in (6, 2):
        controller = RollingGaitController(planner, disabled_limbs=(disabled,))
        controller.support = (1, 3, 5)
        (first, _, future), *_ = controller._candidates(feet, q.ravel())
        assert first[2] == disabled - 1  # a broken limb in the support is lifted first...
        assert all(t[3] != disabled - 1 for t in (first, *future))  # ...and never lands again


def test_six_beast_rolls_closed_loop():
    from baselines.beast import RollingGait
    from polyenvs.beast.tasks import BeastRollEnv

    env = BeastRollEnv(polyhedron="octahedron")
    policy = RollingGait(env.observation_space, env.action_space, max_tumbles=2)
    obs, _ = env.reset(seed=0)
    state, start = None, True
    for _ in range(5000):
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]))
        start = False
        obs, _, _, _, info = env.step(action)
        if policy._controllers[int(state[0, 0])].phase == "done":
            break
    assert len(policy._controllers[int(state[0, 0])].history) == 2
    assert env.unwrapped.episode_metrics()["distance_m"] > 0.2


def test_righting_stands_a_thrown_beast_up():
    from baselines.beast import Righting
    from polyenvs.beast.tasks import BeastRecoverEnv

    env = BeastRecoverEnv()
    policy = Righting(env.observation_space, env.action_space)
    obs, _ = env.reset(seed=2)
    state, start = None, True
    for _ in range(2000):
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]))
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["episode_metrics"]["success"] == 1.0


def test_lookahead_follows_the_strip_and_tips_back_only_when_allowed(planner):
    q = np.tile(TUCKED, (4, 1))
    for limb, angles in planner.stance_angles((0, 1, 3)).items():
        q[limb] = angles
    feet = planner.feet(q.ravel())
    # After (1234): the strip goes on with (4213); heading back, only a controller allowed to tip back over the last
    # edge does so, with (2143).
    cases = ((False, [0.866, 0.5, 0.0], (3, 1, 0, 2)), (False, [-0.866, -0.5, 0.0], (3, 1, 0, 2)))
    cases += ((True, [-0.866, -0.5, 0.0], (1, 0, 3, 2)),)
    for allow_back, heading, expected in cases:
        controller = RollingGaitController(planner, allow_back=allow_back)
        controller.support, controller.tumbles_done, controller.last_edge = (0, 1, 3), 1, frozenset((0, 1))
        controller.heading_edge, controller.heading_vec = (0, 1), np.array(heading)
        assert controller._candidates(feet, q.ravel())[0][0] == expected
