"""The beast environments: observation layout and sensors, stances that hold, faults, tasks' metrics, divergence,
argument checks, rendering."""

import math
import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; must precede the first MuJoCo GL context
mujoco = pytest.importorskip("mujoco")

import gymnasium as gym  # noqa: E402
from gymnasium.utils.env_checker import check_env  # noqa: E402

from polyenvs.beast import kinematics as K  # noqa: E402
from polyenvs.beast import model as M  # noqa: E402
from polyenvs.beast import sensors as S  # noqa: E402
from polyenvs.beast.env import STANCE_TICKS, TumbleCounter  # noqa: E402
from polyenvs.beast.tasks import BeastRecoverEnv, BeastRollEnv, BeastTumbleEnv, BeastTurnEnv  # noqa: E402

CLASSES = {"Tumble": BeastTumbleEnv, "Roll": BeastRollEnv, "Turn": BeastTurnEnv, "Recover": BeastRecoverEnv}
STEPS = {"Tumble": 3000, "Roll": 8000, "Turn": 8000, "Recover": 2000}
for _name, _cls in CLASSES.items():
    if f"polyenvs/Beast{_name}-v0" not in gym.registry:
        gym.register(
            f"polyenvs/Beast{_name}-v0",
            entry_point=f"{_cls.__module__}:{_cls.__name__}",
            max_episode_steps=STEPS[_name],
        )


def _hold_action(env, obs):
    return obs[env.observation_structure["prev_action"]].copy()


@pytest.mark.parametrize("name", CLASSES)
def test_gymnasium_checker_passes(name):
    env = CLASSES[name]()
    check_env(env, skip_render_check=True)


@pytest.mark.parametrize("name", CLASSES)
def test_info_holds_the_declared_reward_terms_and_metrics(name):
    env = CLASSES[name]()
    _, info = env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(5):
        _, reward, _, _, info = env.step(env.action_space.sample())
        assert [k for k in info if k.startswith("reward_")] == [f"reward_{n}" for n in env.reward_names]
        assert np.isclose(sum(info[f"reward_{n}"] for n in env.reward_names), reward)
        assert "episode_metrics" not in info  # only on the step that ends the episode
        assert list(env.episode_metrics()) == list(env.metric_names)
        assert info["sim_unstable"] is False


@pytest.mark.parametrize("polyhedron, n_limbs", [("tetrahedron", 4), ("octahedron", 6), ("cube", 8)])
@pytest.mark.parametrize("privileged", [False, True])
def test_observation_layout_is_the_agreed_one(polyhedron, n_limbs, privileged):
    env = BeastRollEnv(polyhedron=polyhedron, privileged=privileged)
    nj = 3 * n_limbs
    parts = [("joint_pos", nj), ("joint_vel", nj), ("tilt", 12), ("foot_contact", n_limbs), ("prev_action", nj)]
    if privileged:
        parts += [("body_pos", 3), ("body_quat", 4), ("body_linvel", 3), ("body_angvel", 3)]
    start = 0
    for (name, size), (got, part) in zip(parts, env.observation_structure.items(), strict=True):
        assert got == name and part == slice(start, start + size)
        start += size
    assert env.observation_space.shape == (start,) and env.observation_space.dtype == np.float32
    assert env.action_space.shape == (nj,) and env.action_space.dtype == np.float32
    np.testing.assert_array_equal(env.action_space.low, -1)
    np.testing.assert_array_equal(env.action_space.high, 1)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    if privileged:
        s = env.observation_structure
        np.testing.assert_allclose(obs[s["body_pos"]], env.data.qpos[:3], atol=1e-6)
        np.testing.assert_allclose(obs[s["body_quat"]], env.data.qpos[3:7], atol=1e-6)


@pytest.mark.parametrize("polyhedron", K.POLYHEDRA)
def test_start_stance_holds_with_the_hold_action_and_sensors_agree(polyhedron):
    env = BeastTumbleEnv(polyhedron=polyhedron, privileged=True)
    obs, _ = env.reset(seed=3)
    s = env.observation_structure
    hold = _hold_action(env, obs)
    start = env.data.qpos[:3].copy()
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(hold)
        assert not (terminated or truncated)
    assert np.linalg.norm(env.data.qpos[:2] - start[:2]) < 1e-3 and abs(env.data.qpos[2] - start[2]) < 5e-3
    _, stance = M.stance_orientation(polyhedron)
    expected = np.zeros(env.n_limbs)
    expected[stance] = 1
    np.testing.assert_array_equal(obs[s["foot_contact"]], expected)
    # Encoders read the joints to within half the backlash band; at rest they report no motion.
    half = math.radians(env.backlash_deg) / 2
    assert np.abs(obs[s["joint_pos"]] - env.data.qpos[7:]).max() <= half + 1e-6
    assert np.abs(obs[s["joint_vel"]]).max() < 0.05
    # Tilt switches: an axis reads 1 exactly when it points more than the threshold below the horizontal.
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, env.data.qpos[3:7])
    elevation = np.degrees(np.arcsin((S.TILT_AXES @ rot.reshape(3, 3).T)[:, 2]))
    np.testing.assert_array_equal(obs[s["tilt"]], (elevation < -env.tilt_threshold_deg).astype(np.float32))
    assert 0 < obs[s["tilt"]].sum() < 12
    np.testing.assert_array_equal(obs[s["prev_action"]], hold)
    assert info["reward_ctrl"] < 0 and np.isclose(sum(v for k, v in info.items() if k.startswith("reward_")), reward)


def test_tilt_axes_are_the_icosahedron_vertices():
    axes = S.TILT_AXES
    np.testing.assert_allclose(np.linalg.norm(axes, axis=1), 1)
    angles = np.degrees(np.arccos(np.clip(axes @ axes.T, -1, 1)))
    nearest = np.sort(angles, axis=1)[:, 1:6]
    np.testing.assert_allclose(nearest, 63.4349, atol=1e-3)  # five neighbours at the icosahedron's edge angle
    # Any orientation switches some on and some off: the bits tell which way is down.
    rng = np.random.default_rng(0)
    up = rng.normal(size=(500, 3))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    on = (axes @ up.T) < -math.sin(math.radians(10))
    assert on.any(axis=0).all() and (~on).any(axis=0).all()


def test_backlash_is_a_dead_band():
    joints, misc = np.zeros((S.N_JOINT_ROWS, 1)), np.zeros(S.N_MISC)
    joints[S.LIMIT_LOW], joints[S.LIMIT_HIGH] = -math.pi, math.radians(1.9)
    misc[S.HALF_BAND], misc[S.INV_DT] = math.radians(1.0) / 2, 100.0
    obs = np.zeros(1 * 2 + 12 + 0 + 1, np.float32)
    sensordata = np.array([0.0, 0.0, 0.0, 1.0])  # no limbs: robot-floor count, then the up vector
    readings = []
    for q in np.radians([0.0, 0.3, 2.0, 1.8, 0.5, 2.5]):
        qpos = np.zeros(8)
        qpos[3], qpos[7] = 1.0, q
        warnings = np.zeros(7, np.int32)
        assert not S.sense((qpos, np.zeros(7), sensordata, np.zeros(1), warnings), S.TILT_AXES, joints, misc, obs)
        readings.append(obs[0])
    # Inside the band the motor side does not move; beyond it, it trails the joint by half the band; a joint sunk
    # past its limit (MuJoCo's soft limit) reads the limit, inside the observation space's bounds.
    np.testing.assert_allclose(readings, np.radians([0.0, 0.0, 1.5, 1.5, 1.0, 1.9]), atol=1e-7)


def test_same_seed_same_episode_and_seeds_differ():
    def run(seed):
        env = BeastRecoverEnv()
        env.action_space.seed(1)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(30):
            out.append(env.step(env.action_space.sample())[0])
        return np.array(out)

    a, b, c = run(5), run(5), run(6)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_disabled_limbs_stay_locked_whatever_the_action():
    env = BeastRollEnv(disabled_limbs=(4,))
    obs, _ = env.reset(seed=0)
    start = env.data.qpos[7:].copy()
    env.action_space.seed(0)
    for _ in range(100):
        env.step(env.action_space.sample())
    locked = slice(9, 12)
    assert np.abs(env.data.qpos[7:][locked] - start[locked]).max() < math.radians(0.5)
    assert np.abs(env.data.qpos[7:][:9] - start[:9]).max() > math.radians(5)  # the others moved
    assert env.disabled_limbs == (4,)


@pytest.mark.parametrize("value", [(0,), (5,), ("1",), (True,), (1, 1), 3, "4"])
def test_bad_disabled_limbs_raise(value):
    with pytest.raises(ValueError, match="disabled_limbs|locked_limbs"):
        BeastRollEnv(disabled_limbs=value)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"polyhedron": "sphere"}, "polyhedron"),
        ({"privileged": 1}, "privileged"),
        ({"control": "velocity"}, "control"),
        ({"backlash_deg": -1.0}, "backlash_deg"),
        ({"backlash_deg": True}, "backlash_deg"),
        ({"tilt_threshold_deg": "10"}, "tilt_threshold_deg"),
        ({"ctrl_cost_weight": float("nan")}, "ctrl_cost_weight"),
        ({"physics": {"a3": 0.9}}, "a3"),
        ({"physics": {"mass": 1.0}}, "physics"),
        ({"physics": {"timestep": 0.003}}, "timestep"),
        ({"physics": "heavy"}, "physics"),
        ({"render_mode": "human"}, "render_mode"),
        ({"width": 0}, "width"),
        ({"heading_deg": 400.0}, "heading_deg"),
    ],
)
def test_bad_constructor_arguments_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        BeastRollEnv(**kwargs)


def test_task_arguments_are_checked():
    with pytest.raises(ValueError, match="turn_deg"):
        BeastTurnEnv(turn_deg=float("inf"))
    with pytest.raises(ValueError, match="success_reward"):
        BeastTumbleEnv(success_reward=-1.0)
    with pytest.raises(ValueError, match="success_reward"):
        BeastRecoverEnv(success_reward="10")


def test_physics_parameters_reach_the_model():
    env = BeastRollEnv(physics={"a3": 0.17, "friction": 0.8, "timestep": 0.001})
    assert env.frame_skip == 10 and env.dt == 0.01
    assert np.isclose(env.model.geom_friction[env.model.geom("floor").id, 0], 0.8)
    foot = env.model.geom("limb1_foot")
    assert np.isclose(foot.pos[0], 0.17)


def test_bad_actions_and_options_raise_and_change_nothing():
    env, twin = BeastTumbleEnv(), BeastTumbleEnv()
    obs, _ = env.reset(seed=1)
    twin.reset(seed=1)
    hold = _hold_action(env, obs)
    for bad in (hold * 3, np.full(12, np.nan), hold[:-1], "a", None):
        with pytest.raises(ValueError):
            env.step(bad)
    for options in ({"pose": 1}, {"qpos": np.zeros(3)}, {"qpos": np.full(19, np.nan)}, {"qvel": np.zeros(18)}, 5):
        with pytest.raises(ValueError):
            env.reset(options=options)
    for _ in range(3):
        np.testing.assert_array_equal(env.step(hold)[0], twin.step(hold)[0])


def test_divergence_truncates_with_the_last_finite_observation(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warning to MUJOCO_LOG.TXT in the working directory
    env = BeastRollEnv()
    obs, _ = env.reset(seed=0)
    qpos = env.data.qpos.copy()
    qvel = np.zeros(env.model.nv)
    qvel[6:] = 1e12  # joints spun far beyond anything physical: MuJoCo resets the state and warns
    obs0, _ = env.reset(seed=0, options={"qpos": qpos, "qvel": qvel})
    obs, reward, terminated, truncated, info = env.step(_hold_action(env, obs0))
    assert truncated and not terminated and info["sim_unstable"]
    assert reward == 0.0 and np.isfinite(obs).all()
    np.testing.assert_array_equal(obs, obs0)
    assert all(np.isfinite(v) for v in info["episode_metrics"].values())
    obs, *_ = env.reset(seed=0)
    assert not env.step(_hold_action(env, obs))[4]["sim_unstable"]
    assert (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_roll_metrics_follow_the_body_along_the_heading():
    env = BeastRollEnv(heading_deg=90.0)
    obs, _ = env.reset(seed=2)
    start = env.data.qpos[:2].copy()
    env.action_space.seed(2)
    total = 0.0
    for _ in range(100):
        obs, reward, _, _, info = env.step(env.action_space.sample())
        total += info["reward_forward"]
    moved = env.data.qpos[:2] - start
    m = env.episode_metrics()
    assert np.isclose(m["distance_m"], moved[1])  # heading 90 degrees: along +y
    assert np.isclose(m["speed_m_s"], moved[1] / 1.0)
    assert np.isclose(total * env.dt, moved[1])  # the forward term integrates to the distance
    assert m["tumbles"] == 0


def test_roll_start_stance_puts_the_strip_along_the_heading():
    # K0 turned so that foot 3 -> foot 2 (the straight strip's direction) points along the heading.
    env = BeastRollEnv(heading_deg=0.0)
    env.reset(seed=0)
    feet = np.array([env.data.geom(f"limb{i}_foot").xpos[:2] for i in (1, 2, 3)])
    strip = feet[1] - feet[2]
    assert abs(math.degrees(math.atan2(strip[1], strip[0]))) < 2.5  # within the 2-degree yaw noise


def _k3_qpos(params):
    """The working tumble's end stance K3: limbs 1, 4, 2 down on the K0 pattern, limb 3 straight up."""
    theta = np.radians([[120, 56.0, 115.8], [0, 56.0, 115.8], [0, 90, 0], [-120, 56.0, 115.8]])
    z = K.limb_directions()[2]
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    rot = np.stack([x, np.cross(z, x), z])
    feet = K.foot_in_body(theta) @ rot.T
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.ravel())
    return np.concatenate([[0, 0, -feet[0, 2] + params.foot_radius], quat, theta.ravel()])


def test_tumble_success_when_limbs_1_4_2_stand_and_3_is_free():
    env = BeastTumbleEnv()
    obs, _ = env.reset(seed=0)
    start = _hold_action(env, obs)
    for _ in range(STANCE_TICKS + 5):  # the start stance registers as where the robot stands
        env.step(start)
    k3 = _k3_qpos(env.params)
    # Teleport the robot into the end stance mid-episode (as if it had tumbled) and hold it there.
    env.data.qpos[:] = k3
    env.data.ctrl[:] = k3[7:]
    hold = env.control_to_action(k3[7:])
    for _ in range(STANCE_TICKS + 5):
        obs, reward, terminated, truncated, info = env.step(hold)
        if terminated:
            break
    assert terminated and info["episode_metrics"]["success"] == 1.0
    assert info["reward_success"] == env.success_reward
    np.testing.assert_array_equal(obs[env.observation_structure["foot_contact"]], [1, 1, 0, 1])


def test_tumble_counter_needs_a_roll_not_just_a_new_foot():
    start = np.zeros(19)
    start[3] = 1.0
    counter = TumbleCounter(0b0111, start)
    # A different support without rolling the body (a foot re-placed) is not a tumble.
    for _ in range(STANCE_TICKS + 1):
        assert not counter.update(0b1011, 3, start)
    assert counter.count == 0
    rolled = start.copy()
    half = math.radians(109.47) / 2
    rolled[3:7] = [math.cos(half), 0, math.sin(half), 0]
    results = [counter.update(0b1101, 3, rolled) for _ in range(STANCE_TICKS + 1)]
    assert results.count(True) == 1 and counter.count == 1

    # The 6-beast lands after about 30 degrees and turns the rest of its 70.5 standing on the new feet: the tumble
    # counts once the turn passes 45 degrees on that support, once.
    def turned(deg):
        q = rolled.copy()
        extra = math.radians(deg) / 2
        q[3:7] = [math.cos(half + extra), 0, math.sin(half + extra), 0]
        return q

    results = [counter.update(0b1110, 3, turned(30)) for _ in range(STANCE_TICKS + 5)]
    results += [counter.update(0b1110, 3, turned(deg)) for deg in np.linspace(30, 70.5, 50)]
    assert results.count(True) == 1 and counter.count == 2 and results.index(True) > STANCE_TICKS + 5


def test_recover_starts_in_the_air_and_reports_success_in_a_stance():
    env = BeastRecoverEnv()
    quats = []
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        assert env.data.ncon == 0  # airborne, no limb overlaps another
        assert env.data.qpos[2] > 0.15
        quats.append(env.data.qpos[3:7].copy())
    assert len({tuple(np.round(q, 6)) for q in quats}) == 5
    # Put it down in the start stance: a stance on three feet, nothing else touching, still -> success.
    obs, _ = env.reset(seed=0, options={"qpos": M.stance_qpos(env.params, *M.START_STANCE["tetrahedron"])})
    hold = _hold_action(env, obs)
    for _ in range(STANCE_TICKS + 5):
        obs, reward, terminated, truncated, info = env.step(hold)
        if terminated:
            break
    assert terminated and info["episode_metrics"]["success"] == 1.0
    assert info["episode_metrics"]["time_to_stance_s"] < 0.05


def test_turn_reports_heading_over_two_tumbles():
    env = BeastTurnEnv(turn_deg=-60.0)
    _, info = env.reset(seed=0)
    assert "episode_metrics" not in info and env.episode_metrics()["heading_error_deg"] == 180.0
    assert env.heading_rad == math.radians(-60.0)


def _render_or_skip(env):
    try:
        return env.render()
    except Exception as exc:  # no OpenGL: only the rendering tests skip
        pytest.skip(f"no OpenGL for MuJoCo's renderer here (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {exc}")


def test_render_rgb_array_follows_the_torso():
    env = BeastRollEnv(render_mode="rgb_array", width=160, height=120)
    obs, _ = env.reset(seed=0)
    first = _render_or_skip(env)
    assert first.shape == (120, 160, 3) and first.dtype == np.uint8
    qpos = env.data.qpos.copy()
    qpos[:2] += [3.0, -2.0]  # far away on the floor: a fixed camera would lose it
    env.reset(seed=0, options={"qpos": qpos})
    moved = env.render()
    assert moved.shape == first.shape
    # The camera (and the light) track the torso, so the orange body is drawn in the same place.
    body_first = (first[..., 0] > 150) & (first[..., 2] < 90) & (first[..., 1] < 160)
    body_moved = (moved[..., 0] > 150) & (moved[..., 2] < 90) & (moved[..., 1] < 160)
    assert body_first.sum() > 50
    assert (body_first & body_moved).sum() > 0.9 * body_first.sum()
    env.close()


def test_torque_control_acts_as_torques():
    # Zero torque: the limbs give (slowed by the drives' damping) and the body sinks, where the position servos hold
    # it within a few millimetres (test above); full torque on one joint swings it.
    limp = BeastTumbleEnv(control="torque")
    limp.reset(seed=0)
    height = limp.data.qpos[2]
    for _ in range(100):
        limp.step(np.zeros(12, np.float32))
    assert limp.data.qpos[2] < height - 0.008
    np.testing.assert_allclose(limp.data.ctrl, 0)
    push = BeastTumbleEnv(control="torque")
    obs, _ = push.reset(seed=0)
    action = np.zeros(12, np.float32)
    action[11] = 1.0  # limb 4's joint 3 (free, straight up): +6 N m
    push.step(action)
    assert push.data.ctrl[11] == push.params.torque_limit
    for _ in range(50):
        push.step(action)
    assert push.data.qpos[7 + 11] > math.radians(30)


def test_encoder_bounds_are_the_joint_limits_and_the_turn_observes_its_command():
    roll = BeastRollEnv()
    s = roll.observation_structure
    np.testing.assert_allclose(roll.observation_space.high[s["joint_pos"]][:3], np.radians([180, 160, 150]), rtol=1e-6)
    np.testing.assert_allclose(
        roll.observation_space.low[s["joint_pos"]][:3], np.radians([-180, -120, -150]), rtol=1e-6
    )
    assert "command" not in s
    # The sharp turn winds a planted limb's joint 1 past a half-turn: its default range is +-250 degrees, kept when
    # other physics are given, and the commanded turn is the observation's last part.
    turn = BeastTurnEnv(turn_deg=-60.0, physics={"friction": 0.8})
    s = turn.observation_structure
    assert list(s)[-1] == "command" and s["command"] == slice(52, 54)
    assert turn.params.joint1_high_deg == 250.0 and turn.params.friction == 0.8
    np.testing.assert_allclose(turn.observation_space.high[s["joint_pos"]][0], np.radians(250), rtol=1e-6)
    obs, _ = turn.reset(seed=0)
    np.testing.assert_allclose(obs[s["command"]], [0.5, -math.sqrt(3) / 2], atol=1e-6)
    obs, *_ = turn.step(turn.control_to_action(turn.data.qpos[7:]))
    np.testing.assert_allclose(obs[s["command"]], [0.5, -math.sqrt(3) / 2], atol=1e-6)
    assert turn.observation_space.contains(obs)
    assert BeastTurnEnv(physics={"joint1_low_deg": -180.0}).params.joint1_low_deg == -180.0
    with pytest.raises(ValueError, match="joint1_high_deg"):
        BeastTurnEnv(physics={"joint1_high_deg": 300.0})


def test_a_fall_onto_the_body_is_not_a_tumble():
    start = np.zeros(19)
    start[3] = 1.0
    rolled = start.copy()
    half = math.radians(109.47) / 2
    rolled[3:7] = [math.cos(half), 0, math.sin(half), 0]
    counter = TumbleCounter(0b0111, start)
    # Three feet down after rolling over, but the body lies on the floor too: fallen, not standing.
    assert not any(counter.update(0b1011, 3, rolled, other_contacts=2) for _ in range(3 * STANCE_TICKS))
    assert counter.count == 0
    # It pushes itself up onto the same feet: now it is a stance, and the roll counts once.
    results = [counter.update(0b1011, 3, rolled) for _ in range(2 * STANCE_TICKS)]
    assert results.count(True) == 1 and counter.count == 1
