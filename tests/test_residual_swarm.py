"""Residual agents over the PettingZoo swarms' robots (:class:`baselines.residual.ParallelResidualPolicy`,
``polyenvs train polyenvs.swarm.corridor_v0 --residual paper``): parameter sharing, a baseline memory row per robot,
and a zero correction that is the paper's swarm episode bit for bit, in the wrapper and in a loaded agent.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from baselines import make_policy
from baselines.residual import ParallelResidualPolicy, ResidualSpec
from polyenvs.evaluation.rollout import agent_spaces, make_env, run_episode
from tests.cli_helpers import run_main

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

CORRIDOR, FIELD, FORMATION = (
    "polyenvs.swarm.corridor_v0",
    "polyenvs.swarm.obstacle_field_v0",
    "polyenvs.swarm.formation_v0",
)
#: Short swarm episodes, for training; the episodes compared run in full (1-2 s each): robots reach the goal and
#: leave at different cycles, which a robot's memory row must survive.
SHORT = {"max_cycles": 150}


class _Zero:
    """No correction, for every robot."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros((len(observation), 2), np.float32), None


def _paper_episode(env_id: str, seed: int) -> dict:
    env = make_env(env_id)
    return run_episode(env, make_policy("paper", env_id, *agent_spaces(env)), seed)


@pytest.mark.parametrize("env_id", [CORRIDOR, FIELD, FORMATION])
def test_a_zero_correction_is_the_papers_swarm_episode(env_id):
    wrapper = ParallelResidualPolicy(make_env(env_id), "paper", 0.5)
    first = wrapper.possible_agents[0]
    size = wrapper.env.observation_space(first).shape[0]
    assert wrapper.observation_space(first).shape == (size + 2,)
    for seed in (11, 12):  # one wrapper for both: each robot's memory restarts with the swarm's episode
        assert run_episode(wrapper, _Zero(), seed) == _paper_episode(env_id, seed)


def test_bad_corrections_raise_and_change_nothing():
    wrapper = ParallelResidualPolicy(make_env(CORRIDOR, SHORT))
    observations, _ = wrapper.reset(seed=3)
    zero = {name: np.zeros(2, np.float32) for name in wrapper.agents}
    for bad in ({**zero, wrapper.agents[0]: np.array([2.0, 0.0])}, {wrapper.agents[0]: np.zeros(2)},
                {**zero, "robot_99": np.zeros(2)}, {**zero, wrapper.agents[1]: np.array([np.nan, 0.0])}):  # fmt: skip
        with pytest.raises(ValueError, match="actions"):
            wrapper.step(bad)
    after = wrapper.step(zero)[0]
    clean = ParallelResidualPolicy(make_env(CORRIDOR, SHORT))
    clean.reset(seed=3)
    expected = clean.step(zero)[0]
    assert after.keys() == expected.keys()
    for name in after:
        np.testing.assert_array_equal(after[name], expected[name])


@pytest.mark.parametrize(("kwargs", "name"), [({"baseline": "random"}, "baseline"), ({"scale": 0}, "scale"),
                                              ({"env_id": "not.a_swarm"}, "baseline")])  # fmt: skip
def test_bad_arguments_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ParallelResidualPolicy(make_env(CORRIDOR, SHORT), **kwargs)


def _untrained_swarm_agent(env_id: str, out):
    from stable_baselines3 import PPO

    from polyenvs.evaluation.episodes import resolve_env
    from polyenvs.training.residual import residual_wrapper, start_at_the_base
    from polyenvs.training.vec_adapter import make_training_vec_env

    spec = ResidualSpec("paper", 0.3)
    target = resolve_env(env_id)
    venv = make_training_vec_env(target, 1, seed=0, wrappers=[residual_wrapper(spec, env_id, parallel=True)])
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [16]})
    start_at_the_base(model, -3.0)
    venv.close()
    out.mkdir(parents=True)
    model.save(out / "model.zip")
    (out / "run.json").write_text(json.dumps({"env_id": env_id, "algo": "ppo", "seed": 0, "residual": spec.to_json()}))


@pytest.mark.parametrize("env_id", [CORRIDOR, FORMATION])
def test_an_untrained_swarm_residual_agent_evaluates_as_the_paper(env_id, tmp_path, capsys):
    _untrained_swarm_agent(env_id, tmp_path / "agent")
    common = ["--episodes", "2", "--seed", "100", "--json"]
    code, ours, stderr = run_main(["evaluate", env_id, "--policy", str(tmp_path / "agent"), *common], capsys)
    assert code == 0, stderr
    code, theirs, stderr = run_main(["evaluate", env_id, "--policy", "paper", *common], capsys)
    assert code == 0, stderr
    ours, theirs = json.loads(ours), json.loads(theirs)
    assert ours["episodes"] == theirs["episodes"]
    assert ours["policy_description"]["residual"]["baseline"] == "paper"


def test_train_residual_on_a_swarm_writes_a_run_that_evaluate_loads(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", CORRIDOR, "--algo", "ppo", "--residual", "paper", "--residual-log-std", "-2", "--timesteps",
            "256", "--n-envs", "2", "--env-kwargs", json.dumps(SHORT), "--out", str(out), "--no-progress"]  # fmt: skip
    code, _, stderr = run_main(argv, capsys)
    assert code == 0, stderr
    run = json.loads((out / "run.json").read_text())
    assert run["residual"]["baseline"] == "paper" and run["completed"] is True
    assert run["vec_env"] == "ParallelVecEnvAdapter"
    argv = ["evaluate", CORRIDOR, "--policy", str(out), "--episodes", "1", "--env-kwargs", json.dumps(SHORT), "--json"]
    code, stdout, stderr = run_main(argv, capsys)
    assert code == 0, stderr
    assert json.loads(stdout)["policy_description"]["residual"]["scale"] == 0.5
