"""polyenvs/BumperCartExplore-v0: the API conventions, determinism, metrics, rendering and the random bounce."""

from __future__ import annotations

import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import polyenvs  # noqa: F401  (registers the ids)
from baselines.bumper import RandomBounce
from polyenvs.bumper import cart as C
from polyenvs.bumper.env import OBSERVATION_STRUCTURE, BumperCartExploreEnv
from polyenvs.bumper.maps import MAPS

ENV_ID = "polyenvs/BumperCartExplore-v0"


def _rollout(env, seed, steps, policy_seed=0):
    policy = RandomBounce(env.observation_space, env.action_space, seed=policy_seed)
    obs, info = env.reset(seed=seed)
    trace = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(policy.predict(obs)[0])
        trace.append(np.concatenate([obs, [reward], info["pose"], info["dead_reckoned_pose"]]))
    return trace, info


def test_checkers():
    env = gym.make(ENV_ID)
    check_env(env.unwrapped)
    from stable_baselines3.common.env_checker import check_env as sb3_check

    sb3_check(BumperCartExploreEnv(), warn=True)


def test_same_seed_same_episode_bit_for_bit():
    a, _ = _rollout(gym.make(ENV_ID), 5, 60)
    b, _ = _rollout(gym.make(ENV_ID), 5, 60)
    c, _ = _rollout(gym.make(ENV_ID), 6, 60)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_observation_is_ticks_and_bump_only():
    env = BumperCartExploreEnv()
    obs, info = env.reset(seed=0)
    assert not obs.any() and env.observation_structure == OBSERVATION_STRUCTURE
    for turn in (0.5, -0.25, 1.0, -1.0):
        obs, reward, terminated, truncated, step_info = env.step(np.array([turn], dtype=np.float32))
        assert obs in env.observation_space and (obs == np.rint(obs)).all() and obs[6] in (0.0, 1.0)
        assert obs is not env._observations[0] and not np.shares_memory(obs, env._observations)
        assert set(step_info) == set(info)
        assert reward == step_info["reward_touch"] and math.isfinite(reward)
        assert not terminated and not truncated
    # A turn of +1 is half a revolution counter-clockwise: the right wheel runs forward.
    env.step(np.array([1.0], dtype=np.float32))
    left, right = env.state[0, C.TICKS : C.TICKS + 2]
    assert right > 0 > left and (right - left) * env.model.packed()[
        C.P_TICK
    ] / env.model.wheel_base_cm == pytest.approx(math.pi, abs=0.03)


def test_metrics_and_rewards_add_up():
    env = gym.make(ENV_ID)
    policy = RandomBounce(env.observation_space, env.action_space, seed=1)
    obs, info = env.reset(seed=2)
    total, bumps = 0.0, 0
    truncated = False
    while not truncated:
        obs, reward, _, truncated, info = env.step(policy.predict(obs)[0])
        total += reward
        bumps += int(obs[6])
    m = env.unwrapped.episode_metrics()  # truncated by the TimeLimit, outside the env
    assert m["bumps"] == bumps == 200 or m["bumps"] == bumps
    assert total == pytest.approx(100 * m["wall_fraction_touched"])
    raw = env.unwrapped
    assert m["wall_fraction_touched"] == pytest.approx(raw._cell_share[raw._touched[0] > 0].sum())
    assert info["touched_cells"] == int(raw._touched[0].sum())
    gap = info["pose"][:2] - info["dead_reckoned_pose"][:2]
    assert m["odometry_error_cm"] == pytest.approx(math.hypot(*gap))
    assert 0 <= m["large_slips"] <= bumps


def test_random_bounce_touches_most_of_the_papers_arena():
    """The paper's random bounce, run long enough, 'should collect enough points to make a map'."""
    fractions = []
    for seed in range(5):
        env = gym.make(ENV_ID)
        _, info = _rollout(env, seed, 200, policy_seed=seed)
        fractions.append(env.unwrapped.episode_metrics()["wall_fraction_touched"])
    assert np.mean(fractions) > 0.6
    # Bouncing straight back and forth touches a few cells only.
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    for _ in range(200):
        *_, info = env.step(np.array([0.0], dtype=np.float32))
    assert env.unwrapped.episode_metrics()["wall_fraction_touched"] < 0.5 * np.mean(fractions)


def test_bad_actions_raise_and_change_nothing():
    env = BumperCartExploreEnv()
    env.reset(seed=0)
    before = env.state.copy()
    for action in (np.array([np.nan], dtype=np.float32), np.array([1.5], dtype=np.float32), np.zeros(2), "left"):
        with pytest.raises(ValueError):
            env.step(action)
    np.testing.assert_array_equal(env.state, before)
    with pytest.raises(gym.error.ResetNeeded):
        BumperCartExploreEnv().step(np.zeros(1, dtype=np.float32))


def _snapshot(core) -> dict:
    """Everything that decides what the cart env does next."""
    arrays = {
        "state": core.state, "normals": core.streams.normals, "cursor": core.streams.cursor,
        "observations": core._observations, "out": core._out, "task": core._task, "touched": core._touched,
        "actions": core._actions,
    }  # fmt: skip
    snap = {name: np.array(value, copy=True) for name, value in arrays.items()}
    snap["rngs"] = [repr(g.bit_generator.state) if g is not None else None for g in core.streams.generators]
    snap["np_random"] = repr(core.np_random.bit_generator.state)
    return snap


def _assert_same(before: dict, after: dict) -> None:
    for name in before:
        if isinstance(before[name], np.ndarray):
            np.testing.assert_array_equal(before[name], after[name], err_msg=name)
        else:
            assert before[name] == after[name], name


#: Turns of a type the action space does not hold: each was cast to a number silently (issue 14: the imaginary part
#: of 0.2+5j was dropped; True became a full half turn; '0.5' and objects passed as numbers).
WRONG_DTYPES = {
    "complex": np.full(1, 0.2 + 5j),
    "complex, no imaginary part": np.full(1, 0.2 + 0j, dtype=np.complex64),
    "object": np.array([0.5], dtype=object),
    "string": np.array(["0.5"]),
    "bytes": np.array([b"0.5"]),
    "bool": np.array([True]),
    "list of bools": [True],
    "list of strings": ["0.5"],
    "list of complex": [0.2 + 5j],
    "timedelta": np.array([1], dtype="timedelta64[s]"),
}


@pytest.mark.parametrize("name", sorted(WRONG_DTYPES))
def test_actions_of_a_wrong_dtype_raise_and_change_nothing(name):
    action = WRONG_DTYPES[name]
    env, twin = gym.make(ENV_ID, map="obstacles"), gym.make(ENV_ID, map="obstacles")
    for e in (env, twin):
        e.reset(seed=3)
        e.step(np.array([0.3], dtype=np.float32))
    before = _snapshot(env.unwrapped)
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    _assert_same(before, _snapshot(env.unwrapped))
    for turn in (-0.7, 0.2):  # and it goes on as its twin, which never saw the bad action
        a, b = env.step(np.array([turn], dtype=np.float32)), twin.step(np.array([turn], dtype=np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[4]["pose"], b[4]["pose"])
    # The vector env: the bad turn in one row refuses the whole batch, changing nothing.
    envs = BumperCartExploreEnv.VectorEnv(num_envs=3, map="obstacles")
    envs.reset(seed=3)
    envs.step(np.full((3, 1), 0.3, dtype=np.float32))
    before = _snapshot(envs._core)
    for batch in ([action] * 3, np.asarray([action] * 3)):  # a list of rows, and one array
        with pytest.raises(ValueError, match="actions"):
            envs.step(batch)
        _assert_same(before, _snapshot(envs._core))


def test_real_turns_of_any_float_or_integer_type_are_accepted():
    env = BumperCartExploreEnv()
    env.reset(seed=0)
    for action in (np.array([0.5], dtype=np.float16), np.array([1]), np.array([-1], dtype=np.int8), [0.25], (0,),
                   np.array([np.uint8(1)])):  # fmt: skip
        env.step(action)
    envs = BumperCartExploreEnv.VectorEnv(num_envs=2)
    envs.reset(seed=0)
    envs.step(np.array([[1], [0]]))
    envs.step([[0.5], [-0.5]])


@pytest.mark.parametrize(
    "kwargs,name",
    [({"map": "atlantis"}, "map"), ({"map": [[(0, 0), (1, 0)]]}, "map"), ({"cell_cm": True}, "cell_cm"),
     ({"cell_cm": 0.1}, "cell_cm"), ({"wheel_base_cm": 12.0}, "wheel_base_cm"), ({"slip_sd": float("inf")}, "slip_sd"),
     ({"snap_prob": 2.0}, "snap_prob"), ({"render_mode": "ansi"}, "render_mode")],
)  # fmt: skip
def test_bad_parameters_name_themselves(kwargs, name):
    with pytest.raises(ValueError, match=name):
        BumperCartExploreEnv(**kwargs)
    with pytest.raises(TypeError, match="floor_plan"):
        BumperCartExploreEnv(floor_plan="paper")


def test_reset_pose_option():
    env = BumperCartExploreEnv()
    _, info = env.reset(seed=0, options={"pose": (60.0, 45.0, 90.0)})
    np.testing.assert_allclose(info["pose"], (60.0, 45.0, 90.0))
    before = env.state.copy()
    generator = env.np_random.bit_generator.state
    for pose in ((1.0, 1.0, 0.0), (60.0, 45.0), (60.0, float("nan"), 0.0), (500.0, 45.0, 0.0)):
        with pytest.raises(ValueError, match="pose"):
            env.reset(options={"pose": pose})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"face": 3})
    np.testing.assert_array_equal(env.state, before)
    assert env.np_random.bit_generator.state == generator


def test_native_vector_env_refuses_nan_turns():
    """(Its parity with SyncVectorEnv is the registry-wide test in tests/test_envs_shared.py.)"""
    native = BumperCartExploreEnv.VectorEnv(num_envs=3, map="maze")
    native.reset(seed=100)
    with pytest.raises(ValueError, match="actions"):
        native.step(np.full((3, 1), np.nan, dtype=np.float32))


@pytest.mark.parametrize("name", sorted(MAPS))
def test_render_every_map_without_changing_the_simulation(name):
    env = BumperCartExploreEnv(map=name, render_mode="rgb_array")
    env.reset(seed=0)
    shapes = set()
    for _ in range(30):
        env.step(np.array([0.7], dtype=np.float32))
        state = env.state.copy()
        frame = env.render()
        np.testing.assert_array_equal(env.state, state)
        shapes.add(frame.shape)
    assert len(shapes) == 1 and frame.dtype == np.uint8
    assert (frame == (200, 40, 40)).all(axis=-1).any()  # the true path is drawn
    assert len(env._paths[0]) <= 3000


def test_pickles_and_rebuilds_from_its_spec():
    env = gym.make(ENV_ID, map="l_room")
    a, _ = _rollout(env, 3, 10)
    clone = pickle.loads(pickle.dumps(env))
    b, _ = _rollout(clone, 3, 10)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    rebuilt = gym.make(env.spec)
    assert rebuilt.unwrapped.world.name == "l_room"


def test_localization_context_describes_the_nominal_cart():
    env = BumperCartExploreEnv(wheel_base_cm=5.0)
    ctx = env.localization_context()
    assert ctx.wheel_base_cm == 5.0 and ctx.world is env.world and ctx.observation_structure == OBSERVATION_STRUCTURE


def test_random_bounce_policy():
    env = BumperCartExploreEnv()
    policy = RandomBounce(env.observation_space, env.action_space, seed=0, min_turn_deg=90.0)
    actions = np.array([policy.predict(np.zeros(7, dtype=np.float32))[0] for _ in range(200)])
    assert actions.shape == (200, 1) and (np.abs(actions) >= 0.5).all() and (np.abs(actions) <= 1.0).all()
    assert (actions > 0).any() and (actions < 0).any()
    batch = policy.predict(np.zeros((4, 7), dtype=np.float32))[0]
    assert batch.shape == (4, 1)
    with pytest.raises(ValueError, match="max_turn_deg"):
        RandomBounce(env.observation_space, env.action_space, min_turn_deg=90.0, max_turn_deg=45.0)


def _expected_info(state_row, touched_row, credits_latest_contact):
    """What ``info`` reports of a cart, read afresh from its state row and touched cells."""
    x, y = (C.LATEST_X, C.LATEST_Y) if credits_latest_contact else (C.CONTACT_X, C.CONTACT_Y)
    return {
        "pose": [state_row[C.X], state_row[C.Y], math.degrees(state_row[C.HEADING])],
        "dead_reckoned_pose": [state_row[C.DR_X], state_row[C.DR_Y], math.degrees(state_row[C.DR_HEADING])],
        "pose_at_bump": [state_row[C.BUMP_X], state_row[C.BUMP_Y], math.degrees(state_row[C.BUMP_HEADING])],
        "contact_point": [state_row[x], state_row[y]],
        "touched_cells": int(np.count_nonzero(touched_row)),
    }


@pytest.mark.parametrize("env_id", ["polyenvs/BumperCartExplore-v0", "polyenvs/BumperCartExplore-v2"])
def test_info_reports_the_state_after_every_reset_and_cycle(env_id):
    """The info's poses, contact and touched cells, which the compiled step keeps for it, are the cart's state at
    every step, across resets (a new episode's start, its own room), single env and vector env alike."""
    env = gym.make(env_id, layouts="test")
    raw = env.unwrapped
    rng = np.random.default_rng(1)
    for episode in range(3):
        _, info = env.reset(seed=episode)
        for _ in range(60):
            expected = _expected_info(raw.state[0], raw._touched[0], raw.credits_latest_contact)
            for key, value in expected.items():
                np.testing.assert_allclose(info[key], value, rtol=1e-15, err_msg=key)
            _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
            if terminated or truncated:
                break
    envs = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", layouts="test")
    core = envs.unwrapped._core
    _, info = envs.reset(seed=5)
    for _ in range(120):  # past v2's 50-cycle budget: its rows restart
        for b in range(3):
            expected = _expected_info(core.state[b], core._touched[b], core.credits_latest_contact)
            for key, value in expected.items():
                np.testing.assert_allclose(info[key][b], value, rtol=1e-15, err_msg=key)
        _, _, _, _, info = envs.step(rng.uniform(-1, 1, (3, 1)).astype(np.float32))
