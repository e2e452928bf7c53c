"""Behaviour cloning from a ``polyenvs collect`` dataset, alone and before PPO (``polyenvs train --bc-from``)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from tests.cli_helpers import run_main

pytest.importorskip("minari")
pytest.importorskip("stable_baselines3")

from polyenvs.errors import InputError  # noqa: E402
from polyenvs.evaluation.agents import find_agents  # noqa: E402
from polyenvs.evaluation.datasets import CollectRequest, collect  # noqa: E402
from polyenvs.evaluation.episodes import evaluate  # noqa: E402
from polyenvs.evaluation.results import load_result, result_path  # noqa: E402
from polyenvs.registry import slug  # noqa: E402

CORRIDOR = "polyenvs/APLiteCorridor-v0"
#: The corridor's paper algorithm and its committed success rate (50 episodes from seed 1000).
PAPER = "aplite"
TINY_CORRIDOR_CONFIG = """\
polyenvs/APLiteCorridor-v0:
  n_envs: 2
  n_timesteps: 256
  policy: 'MlpPolicy'
  normalize: true
  n_steps: 128
  batch_size: 64
  n_epochs: 1
  learning_rate: !!float 1e-4
  policy_kwargs: "dict(net_arch=[64, 64])"
"""


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    """15 of the paper's corridor episodes (seeds 0-14: none of the evaluation seeds)."""
    out = tmp_path_factory.mktemp("bc") / "demos"
    collect(CollectRequest(CORRIDOR, "paper", episodes=15, seed=0, out_dir=out, results_dir="benchmarks/results"))
    return out


def _committed_success(policy: str) -> float:
    doc, why = load_result(result_path("benchmarks/results", CORRIDOR, policy), CORRIDOR, policy)
    assert doc is not None, why
    return doc["summary"]["success_rate"]


def _cloned_model(dataset, env_id=CORRIDOR):
    """A new PPO model on ``env_id`` (VecNormalize, as the config), fitted to ``dataset``."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from polyenvs.training.bc import BehaviourCloning

    torch.set_num_threads(1)
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(env_id)]), gamma=0.99)
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [64, 64]})
    record = BehaviourCloning(dataset, epochs=10).pretrain(model)
    venv.training = False
    return model, venv, record


def test_cloning_the_papers_demonstrations_reaches_most_of_its_score(demos):
    """BC alone (no reinforcement learning): the corridor's success rate on the leaderboard's seeds."""
    from baselines.trained import TrainedPolicy
    from polyenvs.evaluation.episodes import make_env
    from polyenvs.evaluation.rollout import run_episode

    model, normalization, record = _cloned_model(demos)
    agent = TrainedPolicy(model, "ppo", "bc", normalization=normalization)
    env = make_env(CORRIDOR)
    try:
        success = np.mean([run_episode(env, agent, 1000 + i)["metrics"]["success_rate"] for i in range(8)])
    finally:
        env.close()
    paper, random = _committed_success(PAPER), _committed_success("random")
    assert random <= 0.05 and paper >= 0.9
    assert success >= 0.7 * paper, (success, record)
    assert record["fit"]["action_mae"] < 0.1


def test_cloning_a_discrete_policy(tmp_path):
    """Categorical actions: Buckybot's goal seeker (committed success 0.98, random 0.06) from 20 episodes."""
    from baselines.trained import TrainedPolicy
    from polyenvs.evaluation.episodes import make_env
    from polyenvs.evaluation.rollout import run_episode

    goal = "polyenvs/BuckybotGoal-v0"
    collect(
        CollectRequest(goal, "paper", episodes=20, seed=0, out_dir=tmp_path / "demos", results_dir="benchmarks/results")
    )
    model, normalization, record = _cloned_model(tmp_path / "demos", goal)
    agent = TrainedPolicy(model, "ppo", "bc", normalization=normalization)
    env = make_env(goal)
    try:
        success = np.mean([run_episode(env, agent, 1000 + i)["metrics"]["success"] for i in range(10)])
    finally:
        env.close()
    assert success >= 0.7 * 0.98, (success, record)
    assert record["fit"]["action_agreement"] > 0.7


def test_the_statistics_are_the_demonstrations(demos):
    from polyenvs.evaluation.datasets import load_demonstrations

    _, normalization, _ = _cloned_model(demos)
    observations = np.concatenate([obs for obs, _, _ in load_demonstrations(demos).episodes])
    assert np.allclose(normalization.obs_rms.mean, observations.mean(axis=0), atol=1e-3)
    assert np.allclose(normalization.obs_rms.var, observations.var(axis=0), rtol=1e-2, atol=1e-3)


def test_train_bc_from_then_ppo_is_a_policy_everywhere(demos, tmp_path, capsys):
    config = tmp_path / "ppo.yml"
    config.write_text(TINY_CORRIDOR_CONFIG)
    out = tmp_path / "run"
    args = ["train", CORRIDOR, "--algo", "ppo", "--config", str(config), "--bc-from", str(demos), "--bc-epochs",
            "10", "--bc-log-std", "-1.7", "--out", str(out), "--no-progress"]  # fmt: skip
    # The demonstrations are of the default layouts: the run must learn on them too (the Procgen protocol's
    # training layouts by default, which these demonstrations are not).
    code, _, err = run_main(args, capsys)
    assert code == 2 and "demonstrations on the 'default' layouts, the run trains on 'train'" in err
    assert not out.exists()
    code, _, err = run_main([*args, "--layouts", "default"], capsys)
    assert code == 0, err
    run = json.loads((out / "run.json").read_text())
    bc = run["bc"]
    assert bc["dataset"]["env_id"] == CORRIDOR and bc["dataset"]["policy_name"] == PAPER
    assert bc["dataset"]["episodes"] == 15 and bc["epochs"] == 10 and bc["fit"]["action_mae"] < 0.1
    assert bc["log_std"] == -1.7
    assert run["completed"] and run["timesteps"] >= 256
    # a few hundred PPO steps at a small learning rate keep the cloned behaviour: it reaches the goal
    doc = evaluate(CORRIDOR, str(out), episodes=3, seed=1000)
    assert doc["summary"]["success_rate"] >= 2 / 3, doc["summary"]
    from stable_baselines3 import PPO

    assert np.allclose(PPO.load(out / "model.zip", device="cpu").policy.log_std.detach().numpy(), -1.7, atol=0.05)
    # On the leaderboard it is its own row, <algo>_bc_<the demonstrations' policy>, and nowhere else.
    rows = tmp_path / "agents" / slug(CORRIDOR)
    shutil.copytree(out, rows / "ppo_bc_paper" / "seed0")
    (found,) = find_agents(tmp_path / "agents", CORRIDOR)
    assert (found.algo, found.label, found.key) == ("ppo", "ppo_bc_paper", "agent__ppo_bc_paper__seed0")
    for elsewhere, message in (
        ("ppo", "demonstrations' policy is 'paper', but the directory says None"),
        ("ppo_bc_random", "demonstrations' policy is 'paper', but the directory says 'random'"),
        ("ppo_residual_paper", "residual baseline is None, but the directory says 'paper'"),
    ):
        (rows / sorted(p.name for p in rows.iterdir())[0]).rename(rows / elsewhere)
        with pytest.raises(InputError, match=message):
            find_agents(tmp_path / "agents", CORRIDOR)


def test_a_trained_agent_collects_demonstrations_too(demos, tmp_path, capsys):
    """A training directory is a policy for collect as for evaluate: its episodes replay in the recovered env."""
    import minari

    from polyenvs.evaluation.episodes import make_agent
    from tests.test_datasets import _replay

    config = tmp_path / "ppo.yml"
    config.write_text(TINY_CORRIDOR_CONFIG)
    run_dir = tmp_path / "run"
    code, _, err = run_main(["train", CORRIDOR, "--algo", "ppo", "--config", str(config), "--bc-from", str(demos),
                             "--layouts", "default", "--out", str(run_dir), "--no-progress"], capsys)  # fmt: skip
    assert code == 0, err
    request = CollectRequest(CORRIDOR, str(run_dir), episodes=2, seed=3, out_dir=tmp_path / "agent",
                             env_kwargs={"max_episode_steps": 30})  # fmt: skip
    identifier = collect(request)
    assert identifier == "polyenvs/APLiteCorridor-v0/trained_ppo-v0"
    from polyenvs.evaluation.datasets import _minari_root

    with _minari_root(tmp_path / "agent"):
        dataset = minari.load_dataset(identifier)
    assert dataset.storage.metadata["polyenvs"]["policy_description"]["algo"] == "ppo"
    env = dataset.recover_environment()
    agent = make_agent(str(run_dir), CORRIDOR, env)
    for seed, episode in zip((3, 4), dataset.iterate_episodes(), strict=True):
        observations, actions = _replay(env, agent, seed, None)
        assert np.array_equal(observations, episode.observations) and np.array_equal(actions, episode.actions)


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--bc-epochs", "5"], "--bc-epochs needs --bc-from"),
        (["--bc-log-std", "-2"], "--bc-log-std needs --bc-from"),
        (["--bc-from", "{demos}", "--bc-log-std", "nan"], "--bc-log-std"),
        (["--bc-from", "{demos}", "--bc-epochs", "0"], "--bc-epochs"),
        (["--bc-from", "nowhere"], "--bc-from nowhere"),
        (["--bc-from", "{empty}"], "no Minari dataset"),
        (["--bc-from", "{demos}", "--algo", "sac"], "actor-critic"),
        (["--bc-from", "{demos}", "--residual", "paper"], "exclude each other"),
    ],
)
def test_bad_bc_flags_are_one_line_before_any_work(extra, fragment, demos, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    extra = [e.format(demos=demos, empty=tmp_path / "empty") for e in extra]
    args = ["train", CORRIDOR, "--algo", "ppo", "--out", str(tmp_path / "run"), *extra]
    code, _, err = run_main(args, capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and fragment in lines[0], err
    assert not (tmp_path / "run").exists()


def test_demonstrations_of_another_environment_are_refused(demos, tmp_path, capsys):
    args = [
        "train",
        "polyenvs/APLiteObstacleField-v0",
        "--algo",
        "ppo",
        "--bc-from",
        str(demos),
        "--out",
        str(tmp_path / "run"),
        "--timesteps",
        "64",
        "--n-envs",
        "1",
        "--no-progress",
    ]  # short, were it let through
    code, _, err = run_main(args, capsys)
    assert code == 2 and "not of polyenvs/APLiteObstacleField-v0" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()
