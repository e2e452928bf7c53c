"""The generated MuJoCo model: names, geometry against the kinematics, stances that hold, static torques, checks."""

import math

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from polyenvs.beast import kinematics as K  # noqa: E402
from polyenvs.beast import model as M  # noqa: E402

G = 9.81


def _sim(params=None, **kwargs):
    params = params or M.BeastModelParams(**kwargs)
    model = M.build_model(params)
    return params, model, mujoco.MjData(model)


def _contacts(model, data):
    return sorted({tuple(sorted((model.geom(c.geom1).name, model.geom(c.geom2).name))) for c in data.contact})


def _hold(model, data, qpos, seconds):
    """Start at ``qpos`` at rest with the servos holding its joint angles; return the torso path (n, 3)."""
    data.qpos[:] = qpos
    data.qvel[:] = 0
    data.ctrl[:] = qpos[7:]
    path = []
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
        path.append(data.qpos[:3].copy())
    return np.array(path)


def test_names_and_joint_order_follow_the_agreed_layout():
    params, model, data = _sim()
    assert model.nu == model.njnt - 1 == 12
    for i in range(1, 5):
        for k in range(1, 4):
            joint = model.joint(f"limb{i}_joint{k}")
            assert joint.qposadr[0] == 7 + 3 * (i - 1) + (k - 1)
            assert model.actuator(f"limb{i}_joint{k}").trnid[0] == joint.id
            assert model.actuator(f"limb{i}_joint{k}").id == 3 * (i - 1) + (k - 1)
        model.geom(f"limb{i}_foot")
    for name in ("floor", "torso"):
        model.geom(name)
    model.body("torso")
    model.camera("track")
    assert math.isclose(model.opt.timestep, 0.002)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


@pytest.mark.parametrize("polyhedron", K.POLYHEDRA)
def test_mujoco_feet_sit_where_the_kinematics_puts_them(polyhedron):
    params, model, data = _sim(polyhedron=polyhedron)
    rng = np.random.default_rng(0)
    theta = rng.uniform(-1.5, 1.5, size=(params.n_limbs, 3))
    data.qpos[:3] = [0.1, -0.2, 0.5]
    data.qpos[3:7] = [math.cos(0.3), 0, math.sin(0.3), 0]  # a turn of 0.6 rad about y
    data.qpos[7:] = theta.ravel()
    mujoco.mj_kinematics(model, data)
    expected = K.foot_in_body(theta, params.links, polyhedron) @ K.rot_y(0.6).T + [0.1, -0.2, 0.5]
    feet = np.array([data.geom(f"limb{i}_foot").xpos for i in range(1, params.n_limbs + 1)])
    np.testing.assert_allclose(feet, expected, atol=1e-12)


def test_masses_and_torque_limits():
    params, model, _ = _sim()
    assert math.isclose(model.body_subtreemass[model.body("torso").id], 4.8)
    assert params.total_mass < 5.0  # paper section 2: under 5 kg
    np.testing.assert_allclose(model.actuator_forcerange, [[-6.0, 6.0]] * 12)
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], 300.0)
    np.testing.assert_allclose(np.degrees(model.jnt_range[1:4]), [[-180, 180], [-120, 160], [-150, 150]])
    torque = M.build_model(M.BeastModelParams(control="torque"))
    np.testing.assert_allclose(torque.actuator_ctrlrange, [[-6.0, 6.0]] * 12)


def test_nominal_three_foot_stance_b3_settles_without_drift():
    params, model, data = _sim()
    qpos = M.stance_qpos(params, 0.20389, 0.17733 + params.foot_radius)
    theta = np.degrees(qpos[7:].reshape(4, 3))
    # B3's joint angles (theta1, 70.53, 90), or the equivalent (theta1 +- 180, 109.47, -90).
    np.testing.assert_allclose(theta[:3, 1:], [[70.53, 90.0]] * 3, atol=0.01)
    np.testing.assert_allclose(np.sort(theta[:3, 0]), [-120, 0, 120], atol=1e-9)
    path = _hold(model, data, qpos, 3.0)
    drift = np.linalg.norm(path[-1] - path[len(path) // 3])  # the last 2 s
    assert drift < 0.1e-3
    assert abs(path[-1, 2] - (0.17733 + params.foot_radius)) < 5e-3  # it sags by the servo error only
    feet = [("floor", f"limb{i}_foot") for i in (1, 2, 3)]
    assert _contacts(model, data) == feet  # three feet down, nothing else touches
    assert np.abs(data.actuator_force).max() < params.torque_limit


@pytest.mark.parametrize("polyhedron", K.POLYHEDRA)
def test_start_stance_holds_on_every_polyhedron(polyhedron):
    params, model, data = _sim(polyhedron=polyhedron)
    path = _hold(model, data, M.stance_qpos(params, *M.START_STANCE[polyhedron]), 2.0)
    assert np.linalg.norm(path[-1] - path[len(path) // 2]) < 0.1e-3
    _, stance = M.stance_orientation(polyhedron)
    assert _contacts(model, data) == [("floor", f"limb{i + 1}_foot") for i in stance]
    assert len(stance) == {"tetrahedron": 3, "octahedron": 3, "cube": 4}[polyhedron]


def test_start_stance_is_the_working_tumbles_k0():
    params = M.BeastModelParams()
    qpos = M.stance_qpos(params, *M.START_STANCE["tetrahedron"])
    np.testing.assert_allclose(
        np.degrees(qpos[7:].reshape(4, 3)),
        [[0, 56.0, 115.8], [120, 56.0, 115.8], [-120, 56.0, 115.8], [0, 90, 0]],
        atol=0.1,
    )
    assert qpos[2] == 0.168
    # Limb 4 straight up; the tumble (1234) tips along +x: foot 3 behind, feet 1 and 2 on the edge x = +86.6 mm.
    data_model = M.build_model(params)
    data = mujoco.MjData(data_model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(data_model, data)
    feet = np.array([data.geom(f"limb{i}_foot").xpos for i in range(1, 5)])
    np.testing.assert_allclose(feet[:3, 2], params.foot_radius, atol=1e-12)
    np.testing.assert_allclose(feet[[0, 1], 0], 0.0866, atol=0.2e-3)
    np.testing.assert_allclose(feet[2, :2], [-0.1732, 0], atol=0.2e-3)
    np.testing.assert_allclose(feet[3, :2], [0, 0], atol=1e-9)


def test_four_feet_down_mid_tumble_pose_b3_holds():
    params, model, data = _sim()
    rot = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # body z down, feet 1, 2 on the y axis
    theta = np.radians([[-120, 155.54, -106.36], [-120, 155.54, -106.36], [60, 4.35, -41.31], [60, 4.35, -41.31]])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.ravel())
    qpos = np.concatenate([[0, 0, 0.151 + params.foot_radius], quat, theta.ravel()])
    path = _hold(model, data, qpos, 2.0)
    assert np.linalg.norm(path[-1] - path[len(path) // 2]) < 0.1e-3
    assert _contacts(model, data) == [("floor", f"limb{i}_foot") for i in (1, 2, 3, 4)]
    forces = np.zeros(6)
    support = []
    for j in range(data.ncon):
        mujoco.mj_contactForce(model, data, j, forces)
        support.append(forces[0])
    assert min(support) > 0.05 * params.total_mass * G  # every foot carries load


def test_static_torques_with_limbs_straight_out_and_horizontal_are_within_the_motor_limits():
    """Paper section 2: the motors lift the robot from its hardest configuration, limbs straight out and horizontal.

    The stance limbs point straight out, horizontally, at the azimuths of their axes, the feet carry the robot; the
    body and shoulder housings are kept off the floor only by the limbs (their contacts are switched off: the
    shoulders sit at foot height here, as the robot is about to lift)."""
    params, model, data = _sim()
    for name in ("torso", "limb1_link1", "limb2_link1", "limb3_link1"):
        model.geom_contype[model.geom(name).id] = 0
        model.geom_conaffinity[model.geom(name).id] = 0
    rot, stance = M.stance_orientation("tetrahedron")
    dirs = K.limb_directions() @ rot.T
    shoulder_depth = params.d1 * -dirs[stance[0], 2]
    outward = dirs[stance].copy()
    outward[:, 2] = 0
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    feet_world = dirs[stance] * params.d1 + outward * (params.a2 + params.a3)
    base = K.limb_base_frames()[stance, :3, :3]
    theta = np.tile([0.0, math.pi / 2, 0.0], (4, 1))
    theta[stance] = K.inverse_kinematics(np.einsum("lji,lj->li", base, feet_world @ rot))
    np.testing.assert_allclose(theta[stance, 2], 0, atol=1e-6)  # straight
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.ravel())
    qpos = np.concatenate([[0, 0, shoulder_depth + params.foot_radius], quat, theta.ravel()])
    _hold(model, data, qpos, 2.0)
    torque = np.abs(data.actuator_force.reshape(4, 3))[stance]
    # The feasibility study: 3.4 N m at the shoulder (joint 2), 2.1 N m at the elbow (joint 3).
    np.testing.assert_allclose(torque[:, 1], 3.4, atol=0.15)
    np.testing.assert_allclose(torque[:, 2], 2.1, atol=0.15)
    assert torque.max() < params.torque_limit  # the robot can lift itself
    # A plain static balance gives the same: a third of the weight at the foot against the links' own weight.
    foot_load = params.total_mass * G / 3
    shoulder = foot_load * (params.a2 + params.a3) - G * (
        params.link2_mass * params.a2 / 2
        + params.link3_mass * (params.a2 + (params.a3 - params.foot_radius) / 2)
        + params.foot_mass * (params.a2 + params.a3)
    )
    np.testing.assert_allclose(torque[:, 1], shoulder, rtol=0.05)
    assert _contacts(model, data) == [("floor", f"limb{i}_foot") for i in (1, 2, 3)]


@pytest.mark.parametrize(
    "name, value",
    [
        ("a3", 0.5),
        ("a3", True),
        ("body_mass", "3"),
        ("kp", float("nan")),
        ("torque_limit", 0.0),
        ("timestep", 0.02),
        ("friction", -1.0),
        ("foot_radius", 0.1),
        ("joint2_low_deg", -200.0),
        ("polyhedron", "dodecahedron"),
        ("control", "velocity"),
    ],
)
def test_bad_parameters_raise_value_error_naming_them(name, value):
    with pytest.raises(ValueError, match=name):
        M.BeastModelParams(**{name: value})


def test_family_masses_and_sizes():
    for polyhedron, n in (("tetrahedron", 4), ("octahedron", 6), ("cube", 8)):
        params, model, _ = _sim(polyhedron=polyhedron)
        assert model.nu == 3 * n
        assert math.isclose(model.body_subtreemass[model.body("torso").id], params.total_mass)
