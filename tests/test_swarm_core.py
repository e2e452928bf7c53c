"""The swarm's physics and sensors, and AP-lite's behaviours (the paper's Figures 5-7)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium import spaces

from baselines.swarm import APLite, APLiteGoalSeeking, FormationController
from polyenvs.swarm import core
from polyenvs.swarm import sensors as ir
from polyenvs.swarm.env import observation_structure
from polyenvs.swarm.formation_v0 import OBSERVATION_PARTS
from polyenvs.swarm.layouts import hex_lattice, lattice_pairs

OBS = spaces.Box(-1.0, 1.0, (8 + 3 * 6,), np.float32)
ACT = spaces.Box(-1.0, 1.0, (2,), np.float32)


# --- IR model -----------------------------------------------------------------------------------------------------
def test_ir_conversion_round_trips_the_papers_function():
    cm = np.linspace(10.0, 80.0, 71)
    assert np.allclose(ir.cm_from_raw(ir.raw_from_cm(cm)), cm)
    assert np.allclose(ir.inches_from_raw(ir.raw_from_cm(2.54 * cm / 2.54)), cm / 2.54)
    # The paper's ConvertSensorReadingToInches, literally.
    raw = np.array([90.0, 200.0, 487.8])
    assert np.allclose(ir.inches_from_raw(raw), ((6787.0 / (raw - 3.0)) - 4.0) / 2.54)
    # 30 inches (the reactive range) reads raw 87.63; the rated 10-80 cm is raw 487.8-83.8.
    assert ir.raw_from_cm(30 * 2.54) == pytest.approx(87.63, abs=0.01)
    assert ir.raw_from_cm(10.0) == pytest.approx(487.8, abs=0.1)
    assert ir.raw_from_cm(80.0) == pytest.approx(83.8, abs=0.1)


def test_ir_readings_noise_floor_clamp_and_the_two_scales():
    rng = np.random.default_rng(0)
    n = 20000
    d = np.full(n, 50.0)
    raw = ir.ir_readings(d, rng.standard_normal((n, 2)), rng.random(n))
    cm = ir.cm_from_raw(raw)
    assert abs(np.median(cm) - 50.0) < 0.5 and 1.0 < cm.std() < 3.0  # 3% of 50 cm plus raw sd 2
    far = ir.ir_readings(np.full(n, np.inf), rng.standard_normal((n, 2)), rng.random(n))
    assert far.min() >= 0.0 and far.max() <= ir.IR_FLOOR_RAW_MAX < 30.0  # below AP-lite's filter
    near = ir.ir_readings(np.full(n, 2.0), np.zeros((n, 2)), rng.random(n))
    assert np.allclose(near, ir.raw_from_cm(ir.IR_MIN_CM))  # a GP2D12 reads no closer than 10 cm
    # Maxelbot: raw / 550, 0 = nothing; X80Pro: reading / 80, 1 = nothing, smaller = closer.
    assert np.allclose(ir.observation_from_raw(np.array([0.0, 550.0]), "maxelbot"), [0.0, 1.0])
    x80 = ir.observation_from_raw(ir.raw_from_cm(np.array([20.0, 40.0, 60.0])), "x80pro")
    assert np.allclose(x80, [0.25, 0.5, 0.75])
    assert ir.observation_from_raw(np.array([10.0]), "x80pro")[0] == 1.0
    back = ir.raw_from_observation(x80, "x80pro")
    assert np.allclose(back, ir.raw_from_cm(np.array([20.0, 40.0, 60.0])))
    assert ir.raw_from_observation(np.array([1.0]), "x80pro")[0] == 0.0


# --- AP-lite: the paper's Figures 5-7 -----------------------------------------------------------------------------
def _powers(policy, raw, steps=30, light=0.0):
    obs = np.zeros((1, OBS.shape[0]), np.float32)
    obs[0, :4] = np.asarray(raw) / ir.MAXELBOT_RAW_MAX
    obs[0, 4] = light
    state = None
    for _ in range(steps):
        action, state = policy.predict(obs, state)
    return tuple(np.round(100 * action[0]).astype(int))


def test_aplite_runs_both_motors_at_70_when_clear():
    assert _powers(APLite(OBS, ACT), [0, 0, 0, 0]) == (70, 70)
    assert _powers(APLite(OBS, ACT), [20, 25, 29, 12]) == (70, 70)  # below the raw filter of 30


def test_aplite_obstacle_on_one_side_lowers_the_opposite_motor_linearly():
    """Figures 5 and 6: (left, right) with an obstacle seen by S0 (right) at 25/20/15/10 inches, mirrored for S3:
    the feasibility study's 47/29/15/5 with the other motor at 70."""
    policy = APLite(OBS, ACT)
    expected = {25: 47, 20: 29, 15: 15, 10: 5}
    for inches, power in expected.items():
        raw = float(ir.raw_from_cm(2.54 * inches))
        assert _powers(policy, [raw, 0, 0, 0]) == (power, 70)
        assert _powers(policy, [0, 0, 0, raw]) == (70, power)
    assert _powers(policy, [float(ir.raw_from_cm(2.54 * 35)), 0, 0, 0]) == (70, 70)  # beyond 30 inches: no force


def test_aplite_halts_with_an_obstacle_ahead_on_both_middle_sensors():
    """Figure 7: a wall ahead gives 70 at 25 inches, 60 at 22, 20 at 20 and a halt at 19 (beams at +-15°)."""
    policy = APLite(OBS, ACT)
    for inches, power in {25: 70, 22: 60, 20: 20, 19: 0, 12: 0}.items():
        raw = float(ir.raw_from_cm(2.54 * inches / math.cos(math.radians(15))))
        assert _powers(policy, [0, raw, raw, 0]) == (power, power)
    assert policy.last_stopped.tolist() == [True]


def test_aplite_batched_predict_equals_row_by_row_and_keeps_velocity_state():
    rng = np.random.default_rng(3)
    obs = rng.random((64, OBS.shape[0])).astype(np.float32)
    obs[:, 4] = 2 * rng.random(64) - 1
    for cls in (APLite, APLiteGoalSeeking):
        policy = cls(OBS, ACT)
        state = rng.uniform(50, 250, (64, 1))
        batch, new_state = policy.predict(obs, state)
        assert batch.shape == (64, 2) and new_state.shape == (64, 1)
        for i in range(0, 64, 7):
            single, single_state = policy.predict(obs[i], state[i : i + 1])
            assert np.array_equal(single, batch[i]) and single_state[0, 0] == new_state[i, 0]
        assert (batch >= 0).all() and (batch <= 0.7).all()  # never reverses, capped at MAX_SPEED


def test_goal_seeking_turns_towards_the_light_and_faithful_does_not():
    light_left = 0.25  # bearing +45°
    assert _powers(APLite(OBS, ACT), [0, 0, 0, 0], light=light_left) == (70, 70)
    left, right = _powers(APLiteGoalSeeking(OBS, ACT), [0, 0, 0, 0], light=light_left)
    assert right == 70 and left < 30


def test_formation_springs_pull_towards_a_far_neighbour_and_push_from_a_near_one():
    formation_obs = spaces.Box(-1.0, 1.0, (12 + 3 * 6,), np.float32)
    structure = observation_structure(6, OBSERVATION_PARTS)
    policy = FormationController(formation_obs, ACT, spacing_m=0.9, spring_k=300.0, comm_range_m=3.0)
    a = structure["neighbours"][0]
    obs = np.zeros((2, formation_obs.shape[0]), np.float32)
    obs[:, a : a + 3] = [[1.2 / 3.0, 0.5, 1.0], [0.6 / 3.0, 0.5, 1.0]]  # a neighbour on the left, far / near
    fx, fy = policy.extra_force(obs)
    assert fy[0] == pytest.approx(300 * 0.3, abs=1e-3) and fy[1] == pytest.approx(-300 * 0.3, abs=1e-3)
    obs[:, a : a + 3] = [[1.5 / 3.0, 0.5, 1.0], [1.2 / 3.0, 0.5, 0.0]]  # beyond 1.5 R; masked
    assert np.allclose(policy.extra_force(obs), 0.0)


def test_bad_policy_parameters_name_the_parameter():
    with pytest.raises(ValueError, match="platform"):
        APLite(OBS, ACT, platform="sonar")
    with pytest.raises(ValueError, match="sensors"):
        APLite(OBS, ACT, sensors=(0, 4))
    with pytest.raises(ValueError, match="spring_k"):
        FormationController(spaces.Box(-1, 1, (30,), np.float32), ACT, spring_k=float("nan"))


# --- the batched core ---------------------------------------------------------------------------------------------
def _world(n, rng, box=6.0):
    walls = np.array([[0, 0, box, 0], [box, 0, box, box], [box, box, 0, box], [0, box, 0, 0]], dtype=np.float64)
    circles = np.array([[3.0, 3.0, 0.4], [1.5, 4.5, 0.3]])
    xy = []
    while len(xy) < n:
        p = rng.uniform(0.3, box - 0.3, 2)
        if np.hypot(*(circles[:, :2] - p).T).min() > 0.9 and all(np.hypot(*(p - q)) > 0.3 for q in xy):
            xy.append(p)
    pose = np.column_stack([np.array(xy), rng.uniform(-np.pi, np.pi, n)])
    return walls, circles, pose


def _segment_distance(p, w):
    """Distance from point p to segment w = (x0, y0, x1, y1), written apart from the simulator."""
    a, b = np.asarray(w[:2], float), np.asarray(w[2:], float)
    t = np.clip(np.dot(p - a, b - a) / max(np.dot(b - a, b - a), 1e-300), 0.0, 1.0)
    return float(np.hypot(*(a + t * (b - a) - p)))


def _gaps(pose, walls, circles, radius):
    wall = min(_segment_distance(p, w) for p in pose[:, :2] for w in walls) - radius
    circle = (np.hypot(*(pose[:, None, :2] - circles[None, :, :2]).transpose(2, 0, 1)) - circles[:, 2] - radius).min()
    d = np.hypot(*(pose[:, None, :2] - pose[None, :, :2]).transpose(2, 0, 1)) + np.eye(len(pose)) * 1e9
    return wall, circle, d.min() - 2 * radius


def test_no_robot_ever_passes_through_a_wall_an_obstacle_or_another_robot():
    rng = np.random.default_rng(7)
    radius, n = 0.14, 60
    walls, circles, pose = _world(n, rng)
    grid = core.Grid((0.0, 0.0, 6.0, 6.0), core.cell_size(radius, 0.8, 1.0, 0.1), n)
    active = np.ones(n, np.uint8)
    params = np.array([0.1, 0.22, radius])
    proposal, blocked = np.zeros((n, 3)), np.zeros(n, np.uint8)
    contacts = 0
    for _ in range(400):
        wheels = rng.uniform(-0.5, 1.0, (n, 2)) * 0.75  # up to 0.075 m a step, below the radius
        core.build_grid(pose, active, grid.arrays)
        core.move(pose, active, wheels, params, (walls[None], circles[None]), grid.arrays, (proposal, blocked))
        contacts += int(blocked.sum())
        assert min(_gaps(pose, walls, circles, radius)) >= -1e-12
        assert (pose[:, :2] > 0).all() and (pose[:, :2] < 6).all()
    assert contacts > 100  # the test did push robots into things


def test_beams_and_trilateration_match_brute_force():
    rng = np.random.default_rng(11)
    radius, n, k = 0.14, 80, 5
    walls, circles, pose = _world(n, rng, box=8.0)
    active = np.ones(n, np.uint8)
    active[::9] = 0
    angles = np.radians([-60.0, -15.0, 15.0, 60.0])
    comm = 1.5
    grid = core.Grid((0.0, 0.0, 8.0, 8.0), core.cell_size(radius, 0.8, comm, 0.1), n)
    core.build_grid(pose, active, grid.arrays)
    beams, idx, rng_out, clearance = np.zeros((n, 4)), np.zeros((n, k), np.int64), np.zeros((n, k)), np.zeros(n)
    params, todo = np.array([radius, 0.8, comm]), np.ones(n, np.uint8)
    core.sense(pose, active, todo, params, angles, (walls[None], circles[None]), grid.arrays,
               (beams, idx, rng_out, clearance))  # fmt: skip
    # Brute force: sample points densely along each beam against every disc and wall.
    t = np.linspace(0.0, 0.8, 8001)
    for i in np.flatnonzero(active)[:30]:
        others = [j for j in np.flatnonzero(active) if j != i]
        discs = np.vstack([circles, np.column_stack([pose[others, :2], np.full(len(others), radius)])])
        for s, a in enumerate(angles):
            u = np.array([math.cos(pose[i, 2] + a), math.sin(pose[i, 2] + a)])
            pts = pose[i, :2] + radius * u + t[:, None] * u
            inside = (np.hypot(*(pts[:, None, :] - discs[None, :, :2]).transpose(2, 0, 1)) < discs[:, 2]).any(axis=1)
            inside |= (pts < 0).any(axis=1) | (pts > 8).any(axis=1)
            expected = t[np.argmax(inside)] if inside.any() else np.inf
            assert beams[i, s] == pytest.approx(expected, abs=2e-4) if np.isfinite(expected) else beams[i, s] == np.inf
        d = np.hypot(*(pose[others, :2] - pose[i, :2]).T)
        order = np.argsort(d, kind="stable")
        near = [(others[j], d[j]) for j in order if d[j] <= comm][:k]
        assert [int(v) for v in idx[i, : len(near)]] == [j for j, _ in near]
        assert np.allclose(rng_out[i, : len(near)], [dd for _, dd in near])
        assert (idx[i, len(near) :] == -1).all()
    assert (beams[active == 0] == np.inf).all() and (idx[active == 0] == -1).all()


def test_hexagonal_lattice_of_seven_is_a_hexagon_around_the_leader():
    points = hex_lattice(7, 0.9)
    assert np.allclose(points[0], 0.0)
    assert np.allclose(np.hypot(*points[1:].T), 0.9)
    assert len(lattice_pairs(points, 0.9)) == 12  # six spokes and six rim edges


def test_environments_of_a_batch_never_meet():
    """Two environments of two robots on the same coordinates: each robot sees and touches only its own
    environment's robots and obstacles."""
    radius = 0.14
    walls = np.array([[[0, 0, 4, 0], [4, 0, 4, 4], [4, 4, 0, 4], [0, 4, 0, 0]]], dtype=np.float64)
    circles = np.array([[[2.0, 3.0, 0.3]], [[1e6, 1e6, 0.0]]])  # an obstacle in environment 0 only
    pose = np.array([[1.0, 1.0, 0.0], [1.45, 1.0, np.pi], [1.0, 1.05, 0.0], [1.0, 3.0, 0.0]])
    active = np.ones(4, np.uint8)
    grid = core.Grid((0.0, 0.0, 4.0, 4.0), core.cell_size(radius, 0.8, 1.0, 0.1), 2, 2)
    core.build_grid(pose, active, grid.arrays)
    beams, idx, dist, clearance = np.zeros((4, 4)), np.zeros((4, 1), np.int64), np.zeros((4, 1)), np.zeros(4)
    core.sense(pose, active, np.ones(4, np.uint8), np.array([radius, 0.8, 1.0]), np.radians([-60.0, -15.0, 15.0, 60.0]),
               (walls, circles), grid.arrays, (beams, idx, dist, clearance))  # fmt: skip
    assert idx[:, 0].tolist() == [1, 0, -1, -1]  # robot 2 overlaps robot 0's spot but lives in environment 1
    assert np.isfinite(beams[0, 1:3]).all() and not np.isfinite(beams[2, 1:3]).any()
    assert clearance[2] == pytest.approx(1.0 - radius)  # the wall, not environment 0's robots
    pose[3] = (1.3, 3.0, 0.0)  # facing where environment 0's obstacle is
    core.sense(pose, active, np.ones(4, np.uint8), np.array([radius, 0.8, 1.0]), np.radians([-60.0, -15.0, 15.0, 60.0]),
               (walls, circles), grid.arrays, (beams, idx, dist, clearance))  # fmt: skip
    assert not np.isfinite(beams[3, 1:3]).any()
    wheels = np.full((4, 2), 0.5)
    proposal, blocked = np.zeros((4, 3)), np.zeros(4, np.uint8)
    core.build_grid(pose, active, grid.arrays)
    core.move(pose, active, wheels, np.array([0.1, 0.22, radius]), (walls, circles), grid.arrays, (proposal, blocked))
    assert blocked.tolist() == [0, 0, 0, 0]


def test_the_corridor_baseline_reads_only_the_x80pros_two_outer_sensors():
    """The paper's AP-lite on the X80Pro reads its outer-most sensors only (the platform's controller_sensors, which
    the registry's baseline takes from the platform): an obstacle seen by a middle sensor changes nothing, one seen
    by an outer sensor turns the robot; the Maxelbot's AP-lite reads all four."""
    from baselines import make_policy
    from polyenvs.swarm import corridor_v0, obstacle_field_v0

    for module, read in ((corridor_v0, {0, 3}), (obstacle_field_v0, {0, 1, 2, 3})):
        env = module.parallel_env()
        obs, _ = env.reset(seed=0)
        policy = make_policy("paper", module.__name__, env.observation_space("robot_0"), env.action_space("robot_0"))
        a, _ = policy.structure["ir"]
        clear = obs["robot_0"].copy()[None]
        clear[0, a : a + 4] = 1.0 if module is corridor_v0 else -1.0  # nothing in range (X80Pro: 80 = nothing)
        base = policy.predict(clear, state=None, episode_start=[True])[0]
        changed = set()
        for k in range(4):
            near = clear.copy()
            near[0, a + k] = 0.2 if module is corridor_v0 else 0.6  # an obstacle a few inches away
            if not np.array_equal(policy.predict(near, state=None, episode_start=[True])[0], base):
                changed.add(k)
        assert changed == read, (module.__name__, changed)
