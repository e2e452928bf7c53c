"""A model trained on stacked frames (a config's ``frame_stack``: SB3's ``VecFrameStack``) is a policy on the
environment as registered: it stacks its own observations, in ``predict``'s state, exactly as it trained."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401 - registers the ids
from baselines import make_policy
from polyenvs.evaluation.rollout import policy_action
from tests.cli_helpers import run_main

sb3 = pytest.importorskip("stable_baselines3")

from baselines.trained import TrainedModelError  # noqa: E402

CART = "polyenvs/BumperCartExplore-v1"
FRAMES = 3


@pytest.fixture(scope="module")
def stacked_run(tmp_path_factory) -> Path:
    """PPO on three stacked cycle logs, normalised after stacking (as polyenvs train wraps), briefly trained."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecNormalize

    directory = tmp_path_factory.mktemp("stacked") / "seed0"
    directory.mkdir()
    venv = VecNormalize(VecFrameStack(DummyVecEnv([lambda: gym.make(CART)]), FRAMES))
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, policy_kwargs={"net_arch": [16]})
    model.learn(128)
    model.save(directory / "model.zip")
    venv.save(directory / "vecnormalize.pkl")
    venv.close()
    run = {"env_id": CART, "algo": "ppo", "seed": 0, "timesteps": 128, "completed": True,
           "hyperparams": {"policy": "MlpPolicy", "normalize": {"norm_obs": True}, "frame_stack": FRAMES}}  # fmt: skip
    (directory / "run.json").write_text(json.dumps(run))
    return directory


def _reference_actions(directory: Path, seed: int, steps: int) -> np.ndarray:
    """The model's actions inside the wrappers it trained in: SB3's own VecFrameStack and VecNormalize."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecFrameStack, VecNormalize

    venv = VecNormalize.load(
        str(directory / "vecnormalize.pkl"), VecFrameStack(DummyVecEnv([lambda: gym.make(CART)]), FRAMES)
    )
    venv.training = False
    model = PPO.load(directory / "model.zip", device="cpu")
    venv.seed(seed)
    obs, actions = venv.reset(), []
    for _ in range(steps):  # DummyVecEnv resets itself at the episode's end: the stack restarts there
        action, _ = model.predict(obs, deterministic=True)
        actions.append(action[0])
        obs, *_ = venv.step(action)
    venv.close()
    return np.array(actions)


def test_a_stacked_model_acts_on_the_registered_env_as_inside_its_training_wrappers(stacked_run):
    env = gym.make(CART)
    policy = make_policy(str(stacked_run), CART, env.observation_space, env.action_space)
    assert policy.observation_space.shape == env.observation_space.shape
    assert policy.describe()["frame_stack"] == FRAMES
    obs, info = env.reset(seed=11)
    state, start, actions = None, True, []
    for _ in range(120):  # 50-cycle episodes: the third one starts inside, on a fresh stack
        action, state = policy_action(policy, obs, state, start, info)
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        start = terminated or truncated
        if start:
            obs, info = env.reset()
    env.close()
    np.testing.assert_array_equal(np.array(actions), _reference_actions(stacked_run, 11, 120))


def test_evaluate_takes_a_stacked_model(stacked_run, capsys):
    code, stdout, stderr = run_main(
        ["evaluate", CART, "--policy", str(stacked_run), "--episodes", "2", "--json"], capsys
    )
    assert code == 0, stderr
    assert json.loads(stdout)["policy_description"]["frame_stack"] == FRAMES


@pytest.mark.parametrize(("frames", "message"), [(0, "positive integer"), ("3", "positive integer")])
def test_a_bad_frame_stack_in_run_json_is_named(frames, message, stacked_run, tmp_path):
    copy = tmp_path / "seed0"
    copy.mkdir()
    for name in ("model.zip", "vecnormalize.pkl"):
        (copy / name).write_bytes((stacked_run / name).read_bytes())
    run = json.loads((stacked_run / "run.json").read_text())
    run["hyperparams"]["frame_stack"] = frames
    (copy / "run.json").write_text(json.dumps(run))
    env = gym.make(CART)
    with pytest.raises(TrainedModelError, match=message):
        make_policy(str(copy), CART, env.observation_space, env.action_space)


def test_train_refuses_a_residual_on_stacked_frames_before_any_work(tmp_path, capsys, monkeypatch):
    import polyenvs.training.vec_adapter as adapter

    config = tmp_path / "stacked.yml"
    config.write_text(f"{CART}:\n  policy: 'MlpPolicy'\n  n_timesteps: 64\n  frame_stack: 2\n")
    monkeypatch.setattr(adapter, "make_training_vec_env", lambda *a, **k: pytest.fail("work started"))
    flags = [CART, "--algo", "ppo", "--config", str(config), "--residual", "fixed_turn", "--out", str(tmp_path / "x")]
    code, _, stderr = run_main(["train", *flags], capsys)
    assert code == 2 and "drop frame_stack" in stderr and len(stderr.strip().splitlines()) == 1
