"""Buckybot environment behaviour: starts, reset options, blocked tips, floor plans, observations, metrics."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401
from polyenvs.buckybot.env import ground_truth_parts
from polyenvs.buckybot.floor_plans import BUILTIN_PLANS
from polyenvs.buckybot.sensors import RANGE_MAX_CM

IDS = ["polyenvs/BuckybotWallFollow-v0", "polyenvs/BuckybotExplore-v0", "polyenvs/BuckybotGoal-v0"]


def truth(info: dict) -> dict:
    """The named parts of ``info["ground_truth"]``."""
    return ground_truth_parts(info["ground_truth"])


@pytest.mark.parametrize("plan", [*BUILTIN_PLANS, "random"])
def test_seeded_starts_are_clear_of_walls(plan):
    env = gym.make(IDS[0], floor_plan=plan)
    starts = set()
    for seed in range(25):
        _, info = env.reset(seed=seed)
        assert truth(info)["wall_distance_cm"] > 13.0 + 9.1
        assert info["action_mask"].all()
        starts.add(tuple(np.round(truth(info)["pose"][:2], 3)))
    assert len(starts) == 25  # the initial state is randomised


def test_reset_options_place_the_robot():
    env = gym.make(IDS[0])
    _, info = env.reset(seed=0, options={"pose": (100.0, 150.0, 30.0), "face": 7})
    np.testing.assert_allclose(truth(info)["pose"], [100.0, 150.0, 30.0])
    np.testing.assert_allclose(truth(info)["dead_reckoned_pose"], [100.0, 150.0, 30.0])
    assert info["face"] == 7
    np.testing.assert_allclose(truth(info)["tip_directions_deg"], [30.0, 150.0, 270.0])
    actuators = env.unwrapped.frame_labels()["actuators"]
    assert len(actuators) == 3 and set(actuators) <= set("ABCDEFGHIJKL")


@pytest.mark.parametrize(
    "options, match",
    [
        ({"pose": (5.0, 150.0, 0.0)}, "from a wall"),
        ({"pose": (-50.0, 150.0, 0.0)}, "outside"),
        ({"pose": (1.0, 2.0)}, "pose"),
        ({"pose": (np.nan, 2.0, 0.0)}, "finite"),
        ({"face": 0}, "face"),
        ({"face": 21}, "face"),
        ({"bogus": 1}, "unknown reset option"),
    ],
)
def test_bad_reset_options(options, match):
    env = gym.make(IDS[0])
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options=options)


def test_blocked_tip_stays_put_and_is_flagged():
    env = gym.make(IDS[0])
    # 20 cm from the west wall, frame direction 1 (120°+60° = 180°) points at it.
    _, info = env.reset(seed=0, options={"pose": (20.0, 150.0, 60.0), "face": 1})
    assert info["action_mask"].tolist() == [1, 0, 1]
    obs, reward, _, _, info = env.step(1)
    assert info["blocked"] and info["reward_blocked"] == -1.0
    np.testing.assert_allclose(truth(info)["pose"], [20.0, 150.0, 60.0])
    assert info["face"] == 1
    assert obs[18] == 1.0  # tip_failed
    assert env.unwrapped.episode_metrics()["blocked_tips"] == 1
    obs, *_, info = env.step(0)
    assert not info["blocked"] and obs[18] == 0.0


def test_a_tip_moves_one_lattice_step_and_turns_the_frame():
    env = gym.make(IDS[0], noise_scale=0.0)
    _, info = env.reset(seed=0, options={"pose": (200.0, 150.0, 0.0), "face": 1})
    _, _, _, _, info = env.step(1)
    np.testing.assert_allclose(
        truth(info)["pose"][:2],
        [200.0 + 9.129 * np.cos(np.radians(120)), 150.0 + 9.129 * np.sin(np.radians(120))],
        atol=1e-3,
    )
    assert truth(info)["pose"][2] == pytest.approx(300.0)  # 120° + 180°: direction 0 now points back
    assert info["face"] != 1
    _, _, _, _, info = env.step(0)  # back where it came from, on the same face
    np.testing.assert_allclose(truth(info)["pose"][:2], [200.0, 150.0], atol=1e-9)
    assert info["face"] == 1


def test_too_close_and_no_return_are_distinguishable():
    env = gym.make(IDS[0], range_noise_scale=0.0)
    # Facing the east wall from 25 cm: the sensors flanking direction 0 read too close; the room is 400 wide,
    # so the sensors looking west along the long axis see nothing within 182.88 cm.
    obs, info = env.reset(seed=0, options={"pose": (375.0, 150.0, 0.0)})
    too_close, no_return = obs[6:12].astype(bool), obs[12:18].astype(bool)
    assert too_close[[0, 5]].all() and obs[0] == 0.0
    assert no_return[[2, 3]].all() and obs[2] == 1.0
    valid = ~(too_close | no_return)
    assert ((obs[:6][valid] >= 30.48 / RANGE_MAX_CM - 1e-6) & (obs[:6][valid] <= 1.0)).all()


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"floor_plan": "nowhere"}, "floor_plan"),
        ({"floor_plan": []}, "floor_plan"),
        ({"floor_plan": [(0, 0, 0, 0), (0, 0, 100, 0)]}, "degenerate"),
        ({"floor_plan": [(0, 0, 1, 1, 5)]}, "floor_plan"),
        ({"floor_plan": [(0, 0, 30, 0), (30, 0, 30, 30), (30, 30, 0, 30), (0, 30, 0, 0)]}, "floor_plan"),
        ({"noise_scale": -0.1}, "noise_scale"),
        ({"noise_scale": 2.0}, "noise_scale"),
        ({"range_noise_scale": float("nan")}, "range_noise_scale"),
        ({"heading_sd_deg": -1.0}, "heading_sd_deg"),
        ({"step_forward_cm": 0.0}, "step_forward_cm"),
        ({"body_radius_cm": -3.0}, "body_radius_cm"),
        ({"render_mode": "ascii"}, "render_mode"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*render_mode")
def test_bad_constructor_arguments_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make(IDS[0], **kwargs)


def test_task_argument_errors():
    with pytest.raises(ValueError, match="d_star_cm"):
        gym.make(IDS[0], d_star_cm=0)
    with pytest.raises(ValueError, match="coverage_goal"):
        gym.make(IDS[1], coverage_goal=1.5)
    with pytest.raises(ValueError, match="goal_distance_cm"):
        gym.make(IDS[2], goal_distance_cm=(300, 100))


def test_user_floor_plan():
    walls = [(0, 0, 300, 0), (300, 0, 300, 200), (300, 200, 0, 200), (0, 200, 0, 0), (140, 80, 160, 80)]
    env = gym.make(IDS[0], floor_plan=walls)
    _, info = env.reset(seed=0)
    assert truth(info)["wall_distance_cm"] > 22


def test_random_rooms_follow_the_seed():
    env = gym.make(IDS[1], floor_plan="random")
    env.reset(seed=11)
    first = env.unwrapped.plan.segments.copy()
    env.reset(seed=12)
    assert not np.array_equal(first, env.unwrapped.plan.segments)
    env.reset(seed=11)
    np.testing.assert_array_equal(first, env.unwrapped.plan.segments)


def test_dead_reckoning_drifts_with_noise_and_not_without():
    def gaps(scale):
        out = []
        for seed in range(8):
            env = gym.make(IDS[0], noise_scale=scale)
            env.reset(seed=seed, options={"pose": (200.0, 150.0, 0.0)})
            for a in [1, 0] * 40:  # 80 tips back and forth across the middle of the room
                *_, info = env.step(a)
            out.append(np.hypot(*(truth(info)["pose"][:2] - truth(info)["dead_reckoned_pose"][:2])))
        return np.array(out)

    assert (gaps(0.0) < 1e-9).all()
    # With the paper's noise the gap random-walks: about 1.3 cm after 80 tips (median over seeds), never 0.
    noisy = gaps(1.0)
    assert (noisy > 0.05).all() and np.median(noisy) > 0.5


def test_explore_map_error_grows_with_distance():
    env = gym.make(IDS[1], floor_plan="rectangle")
    errors = []
    for seed in range(4):
        env.reset(seed=seed)
        env.action_space.seed(seed)
        early = None
        for t in range(400):
            *_, info = env.step(env.action_space.sample())
            if t == 20:
                early = env.unwrapped.episode_metrics()["map_error_cm"]
        errors.append((early, env.unwrapped.episode_metrics()["map_error_cm"]))
    assert all(late > early for early, late in errors)


def test_goal_observation_is_dead_reckoned():
    env = gym.make(IDS[2], noise_scale=0.0)
    obs, info = env.reset(seed=0, options={"pose": (100.0, 100.0, 0.0), "goal": (100.0, 300.0)})
    bearing = np.degrees(np.arctan2(obs[20], obs[19]))
    assert bearing == pytest.approx(90.0, abs=1e-4)  # 90° left of frame direction 0
    assert obs[21] == pytest.approx(np.tanh(200.0 / 200.0), abs=1e-6)


def test_goal_success_terminates():
    env = gym.make(IDS[2], noise_scale=0.0)
    env.reset(seed=0, options={"pose": (100.0, 100.0, 0.0), "goal": (109.0, 100.0)})
    _, reward, terminated, truncated, info = env.step(0)
    assert terminated and not truncated
    assert info["reward_goal"] == 10.0 and info["episode_metrics"]["success"] == 1.0


def test_info_maps_the_face_frame_to_the_world():
    """The six observed sensors sit on the faces whose normals point 19.47° up at the frame's sensor azimuths."""
    from polyenvs.buckybot import geometry as geo

    env = gym.make(IDS[0])
    _, info = env.reset(seed=3)
    for _ in range(40):
        face = info["face"] - 1
        heading = np.radians(truth(info)["pose"][2])
        edge0 = int(env.unwrapped.sim.edge0[0])
        body = geo.body_rotation(face, edge0, heading)
        normals = geo.FACE_NORMALS_HOME[np.array(env.unwrapped.frame_labels()["sensor_faces"]) - 1] @ body.T
        np.testing.assert_allclose(np.degrees(np.arcsin(normals[:, 2])), 19.47, atol=0.01)
        world_az = np.degrees(np.arctan2(normals[:, 1], normals[:, 0]))
        expected = np.degrees(heading + geo.SENSOR_AZIMUTHS_RAD)
        np.testing.assert_allclose((world_az - expected + 180) % 360 - 180, 0.0, atol=1e-6)
        # The actuator of each action is the corner opposite that tip direction.
        corners = (
            geo.ACTUATOR_AXES_HOME[[geo.ACTUATOR_LETTERS.index(c) for c in env.unwrapped.frame_labels()["actuators"]]]
            @ body.T
        )
        corner_az = np.degrees(np.arctan2(corners[:, 1], corners[:, 0]))
        np.testing.assert_allclose(
            (corner_az - truth(info)["tip_directions_deg"] - 180 + 180) % 360 - 180, 0.0, atol=1e-6
        )
        *_, info = env.step(env.action_space.sample())


def test_human_render_mode_opens_a_window(monkeypatch):
    """'human' mode draws into a pygame window (SDL's dummy video driver stands in for a display)."""
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    pygame = pytest.importorskip("pygame")
    env = gym.make(IDS[0], render_mode="human")
    env.reset(seed=0)
    assert env.render() is None
    env.step(0)  # human mode renders on every step
    surface = pygame.display.get_surface()
    assert surface is not None and surface.get_size()[0] == 480
    env.close()
    assert pygame.display.get_surface() is None


@pytest.mark.parametrize("env_id", IDS)
def test_info_holds_the_documented_entries(env_id):
    """One step's info: the ground truth as one array laid out as ``ground_truth_structure`` says, the face, the
    mask and the reward terms (the metrics only at the episode's end: tests/test_lean_info.py); the vector env
    gives the same entries for every row."""
    env = gym.make(env_id)
    _, info = env.reset(seed=4)
    *_, info = env.step(1)
    core = env.unwrapped
    task = {"goal"} if "Goal" in env_id else set()
    reward_keys = {f"reward_{name}" for name in core.reward_names}
    assert set(info) == {"ground_truth", "face", "blocked", "action_mask"} | reward_keys | task
    parts = truth(info)
    assert info["ground_truth"].shape == (16,) and set(parts) == set(core.ground_truth_structure)
    state = core.sim.state[0]
    np.testing.assert_array_equal(parts["pose"][:2], core.position)
    np.testing.assert_allclose(parts["pose"][2], np.degrees(state[2]))
    np.testing.assert_allclose(parts["tip_directions_deg"], (parts["pose"][2] + [0.0, 120.0, 240.0]) % 360.0)
    assert parts["wall_distance_cm"] == pytest.approx(core.floor_plan.clearance(core.position))
    assert info["face"] == int(state[3]) + 1
    assert set(core.episode_metrics()) == set(core.all_metric_names)

    vector = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    _, vector_info = vector.reset(seed=4)
    _, _, _, _, vector_info = vector.step(np.ones(3, dtype=np.int64))
    assert {key for key in vector_info if not key.startswith("_")} == set(info)
    assert vector_info["ground_truth"].shape == (3, 16)
    np.testing.assert_array_equal(vector_info["ground_truth"][0], info["ground_truth"])


@pytest.mark.parametrize("env_id", IDS)
def test_a_pickled_env_reports_its_own_steps(env_id):
    """A copy (pickle, deepcopy) rebuilds what it reads its kernel and info through from its own arrays."""
    import copy
    import pickle

    env = gym.make(env_id)
    env.reset(seed=4)
    clones = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    for action in [1, 2, 2, 0, 1, 1]:
        obs, reward, _, _, info = env.step(action)
        for clone in clones:
            clone_obs, clone_reward, _, _, clone_info = clone.step(action)
            np.testing.assert_array_equal(clone_obs, obs)
            assert clone_reward == reward and clone.unwrapped.episode_metrics() == env.unwrapped.episode_metrics()
            np.testing.assert_array_equal(clone_info["ground_truth"], info["ground_truth"])
            np.testing.assert_array_equal(clone_info["action_mask"], info["action_mask"])
