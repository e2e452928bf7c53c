"""Residual policies (:mod:`baselines.residual`, :class:`baselines.residual.ResidualPolicy`, ``train --residual``).

The untrained residual agent is its baseline: a zero correction must reproduce the baseline's episodes exactly, in
the wrapper (training) and in a loaded agent (evaluation), across resets and in a vector env.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import polyenvs  # noqa: F401  (registers the ids)
from baselines import make_policy
from baselines.residual import ResidualComposer, ResidualPolicy, ResidualSpec
from polyenvs.evaluation.episodes import evaluate
from polyenvs.evaluation.rollout import run_episode
from tests.cli_helpers import run_main

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

CORRIDOR, FIELD, CART = "polyenvs/APLiteCorridor-v0", "polyenvs/APLiteObstacleField-v0", "polyenvs/BumperCartExplore-v1"
BEAST = "polyenvs/BeastTumble-v1"
#: Beast episodes cut short: the gait's first tumble takes seconds, 300 ticks are enough to compare.
SHORT = {BEAST: 300}
IDS = [CORRIDOR, FIELD, CART, BEAST]


def _make(env_id: str) -> gym.Env:
    return gym.make(env_id, max_episode_steps=SHORT[env_id]) if env_id in SHORT else gym.make(env_id)


def _zero_episode(wrapper: ResidualPolicy, seed: int) -> dict:
    """One episode of the wrapper with a zero correction: what run_episode records, and every env observation."""
    obs, _ = wrapper.reset(seed=seed)
    size = wrapper.env.observation_space.shape[0]
    total, length, observations = 0.0, 0, [obs[:size]]
    while True:
        obs, reward, terminated, truncated, info = wrapper.step(np.zeros(wrapper.action_space.shape, np.float32))
        total, length = total + float(reward), length + 1
        observations.append(obs[:size])
        if terminated or truncated:
            metrics = wrapper.unwrapped.episode_metrics()  # the TimeLimit truncates outside the env
            return {"return": total, "length": length, "metrics": metrics, "observations": np.array(observations)}


def _baseline_episode(env_id: str, seed: int) -> dict:
    env = _make(env_id)
    policy = make_policy("paper", env_id, env.observation_space, env.action_space, seed=seed)
    return run_episode(env, policy, seed)


def test_combine_keeps_the_base_actions_dtype():
    box = spaces.Box(-1.0, 1.0, (3,), np.float32)
    composer = ResidualComposer(ResidualSpec(scale=0.5), None, spaces.Box(-1, 1, (2,), np.float32), box)
    base = np.array([0.123456789012345, -0.987654321098765, 1.0 / 3.0])  # float64: a float32 cast perturbs it
    same = composer.combine(base, np.zeros(3, np.float32))
    assert same.dtype == np.float64 and same.tobytes() == base.tobytes()
    moved = composer.combine(base.astype(np.float32), np.array([1.0, -1.0, 0.5], np.float32))
    assert moved.dtype == np.float32
    np.testing.assert_allclose(moved, [0.623456789, -1.0, 1 / 3 + 0.25], rtol=1e-6)  # clipped to the space
    observed = composer.observe(np.zeros(2, np.float32), base)
    assert observed.dtype == np.float32 and observed.shape == (5,)


@pytest.mark.parametrize("env_id", IDS)
def test_a_zero_correction_reproduces_the_baseline_exactly(env_id):
    wrapper = ResidualPolicy(_make(env_id), baseline="paper", scale=0.5)
    assert wrapper.observation_space.shape[0] == wrapper.env.observation_space.shape[0] + wrapper.action_space.shape[0]
    for seed in (11, 12, 13):  # one wrapper for every episode: its baseline's memory restarts at each reset
        ours, theirs = _zero_episode(wrapper, seed), _baseline_episode(env_id, seed)
        assert (ours["return"], ours["length"], ours["metrics"]) == (
            theirs["return"],
            theirs["length"],
            theirs["metrics"],
        )


def test_the_baseline_memory_restarts_at_every_reset():
    """The gait keeps its trajectory in a controller named by its memory row: carried over, the second episode
    would continue the first one's trajectory."""
    env_id = BEAST
    wrapper = ResidualPolicy(_make(env_id), baseline="paper", scale=0.1)
    first = _zero_episode(wrapper, 21)
    second = _zero_episode(wrapper, 21)
    fresh = _zero_episode(ResidualPolicy(_make(env_id), baseline="paper", scale=0.1), 21)
    np.testing.assert_array_equal(second["observations"], first["observations"])
    np.testing.assert_array_equal(second["observations"], fresh["observations"])


@pytest.mark.parametrize("env_id", [CART, CORRIDOR])
def test_each_sub_env_of_a_vector_env_runs_its_own_baseline(env_id):
    """SB3's DummyVecEnv of wrapped envs (what ``train --residual`` builds) gives each sub-env what one wrapper
    gives alone: its own baseline, memory and (the cart's random bounce) generator."""
    from polyenvs.evaluation.episodes import resolve_env
    from polyenvs.training.residual import residual_wrapper
    from polyenvs.training.vec_adapter import make_training_vec_env

    spec, n, steps = ResidualSpec("paper", 0.5), 3, 120
    venv = make_training_vec_env(resolve_env(env_id), n, seed=5, wrappers=[residual_wrapper(spec, env_id)])
    assert type(venv).__name__ == "DummyVecEnv"
    venv.reset()
    rewards = np.array([venv.step(np.zeros((n, *venv.action_space.shape), np.float32))[1] for _ in range(steps)])
    venv.close()
    for i in range(n):
        alone = ResidualPolicy(gym.make(env_id), "paper", 0.5)
        alone.reset(seed=5 + i)
        expected = []
        for _ in range(steps):
            _, reward, terminated, truncated, _ = alone.step(np.zeros(alone.action_space.shape, np.float32))
            expected.append(reward)
            if terminated or truncated:
                alone.reset()
        np.testing.assert_array_equal(rewards[:, i], np.float32(expected))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"baseline": "nope"}, "baseline"),
        ({"baseline": "random"}, "baseline"),
        ({"baseline": "benchmarks/agents/x"}, "baseline"),
        ({"baseline": ""}, "baseline"),
        ({"scale": 0.0}, "scale"),
        ({"scale": -0.5}, "scale"),
        ({"scale": 2.5}, "scale"),
        ({"scale": float("nan")}, "scale"),
        ({"observe_base": "yes"}, "observe_base"),
    ],
)
def test_bad_arguments_raise_naming_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ResidualPolicy(gym.make(CORRIDOR), **kwargs)


@pytest.mark.parametrize("env_id", IDS)
def test_a_bad_seed_raises_naming_seed(env_id):
    """``seed="x"``, -1 and 1.5 were accepted (the cart's random bounce failed later, in NumPy, without the name)."""
    env = _make(env_id)
    for seed in ("x", -1, 1.5, True):
        with pytest.raises(ValueError, match="^seed must be "):
            ResidualPolicy(env, seed=seed)
    env.close()


def test_a_discrete_action_space_is_refused_naming_env():
    with pytest.raises(ValueError, match="env: a residual policy needs Box"):
        ResidualPolicy(gym.make("polyenvs/BuckybotGoal-v0"))


@pytest.mark.parametrize("bad", [np.array([2.0, 0.0]), np.array([np.nan, 0.0]), np.zeros(3), "a"])
def test_a_bad_correction_raises_and_changes_nothing(bad):
    wrapper = ResidualPolicy(gym.make(CORRIDOR))
    wrapper.reset(seed=3)
    with pytest.raises(ValueError, match="action"):
        wrapper.step(bad)
    after = [wrapper.step(np.zeros(2, np.float32))[1] for _ in range(20)]
    clean = ResidualPolicy(gym.make(CORRIDOR))
    clean.reset(seed=3)
    assert after == [clean.step(np.zeros(2, np.float32))[1] for _ in range(20)]


def _untrained_residual_agent(env_id: str, out, log_std: float = -3.0):
    """A residual agent's training directory as ``train --residual`` leaves it before any update."""
    from stable_baselines3 import PPO

    from polyenvs.evaluation.episodes import resolve_env
    from polyenvs.training.residual import residual_wrapper, start_at_the_base
    from polyenvs.training.vec_adapter import make_training_vec_env

    spec = ResidualSpec("paper", 0.3)
    venv = make_training_vec_env(resolve_env(env_id), 1, seed=0, wrappers=[residual_wrapper(spec, env_id)])
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [16]})
    start_at_the_base(model, log_std)
    venv.close()
    out.mkdir(parents=True)
    model.save(out / "model.zip")
    run = {"env_id": env_id, "algo": "ppo", "seed": 0, "residual": spec.to_json()}
    (out / "run.json").write_text(json.dumps(run))
    return model


@pytest.mark.parametrize("env_id", [CORRIDOR, CART, BEAST])
def test_an_untrained_residual_agent_evaluates_as_its_baseline(env_id, tmp_path):
    model = _untrained_residual_agent(env_id, tmp_path / "agent")
    assert float(model.policy.log_std.detach().max()) == -3.0
    env_kwargs = {"max_episode_steps": SHORT[env_id]} if env_id in SHORT else None
    ours = evaluate(env_id, str(tmp_path / "agent"), episodes=3, seed=100, env_kwargs=env_kwargs)
    theirs = evaluate(env_id, "paper", episodes=3, seed=100, env_kwargs=env_kwargs)
    assert ours["episodes"] == theirs["episodes"]
    assert ours["policy_description"]["residual"]["baseline"] == "paper"


def test_train_residual_writes_a_run_that_evaluate_loads(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", CORRIDOR, "--algo", "ppo", "--residual", "paper", "--residual-scale", "0.3",
            "--residual-log-std", "-2", "--timesteps", "256", "--n-envs", "2", "--out", str(out), "--no-progress"]  # fmt: skip
    code, stdout, stderr = run_main(argv, capsys)
    assert code == 0, stderr
    run = json.loads((out / "run.json").read_text())
    assert run["residual"] == {"baseline": "paper", "scale": 0.3, "observe_base": True, "hold": 1}
    assert run["residual_log_std"] == -2.0 and run["vec_env"] == "DummyVecEnv" and run["completed"] is True
    code, stdout, stderr = run_main(["evaluate", CORRIDOR, "--policy", str(out), "--episodes", "2", "--json"], capsys)
    assert code == 0, stderr
    assert json.loads(stdout)["policy_description"]["residual"]["scale"] == 0.3


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        ([CORRIDOR, "--residual", "nope"], "baseline 'nope' is not a hand baseline"),
        ([CORRIDOR, "--residual", "paper", "--residual-scale", "0"], "--residual-scale must be > 0"),
        ([CORRIDOR, "--residual", "paper", "--residual-scale", "3"], "--residual-scale must be between"),
        ([CORRIDOR, "--residual-scale", "0.5"], "need --residual NAME"),
        ([CORRIDOR, "--residual", "paper", "--residual-log-std", "5"], "--residual-log-std must be between"),
        (["polyenvs/BuckybotGoal-v0", "--residual", "paper"], "needs Box"),
        (["polyenvs.swarm.corridor_v0", "--residual", "paper", "--residual-hold", "5"], "its residual is not held"),
    ],
)
def test_bad_residual_flags_are_one_line_before_training(flags, message, tmp_path, capsys, monkeypatch):
    import polyenvs.training.vec_adapter as adapter

    monkeypatch.setattr(adapter, "make_training_vec_env", lambda *a, **k: pytest.fail("work started"))
    code, _, stderr = run_main(["train", *flags, "--algo", "ppo", "--out", str(tmp_path / "x")], capsys)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1


def test_the_leaderboard_finds_a_residual_agent_in_its_own_row(tmp_path):
    from polyenvs.evaluation.agents import find_agents
    from polyenvs.registry import slug

    rows = tmp_path / "agents" / slug(CART)
    rows.mkdir(parents=True)
    _untrained_residual_agent(CART, rows / "ppo_residual_paper" / "seed0")
    (found,) = find_agents(tmp_path / "agents", CART)
    assert (found.algo, found.label, found.key) == ("ppo", "ppo_residual_paper", "agent__ppo_residual_paper__seed0")
    (rows / "ppo_residual_paper").rename(rows / "ppo_residual_fixed_turn")  # the run corrects another baseline
    with pytest.raises(ValueError, match="residual baseline is 'paper', but the directory says 'fixed_turn'"):
        find_agents(tmp_path / "agents", CART)


def test_a_finished_plain_run_is_not_taken_for_a_residual_one(tmp_path, capsys):
    out = tmp_path / "run"
    _untrained_residual_agent(CORRIDOR, out)
    run = json.loads((out / "run.json").read_text())
    run.update(completed=True, residual=None)
    (out / "run.json").write_text(json.dumps(run))
    argv = ["train", CORRIDOR, "--algo", "ppo", "--residual", "paper", "--out", str(out), "--no-progress"]
    code, _, stderr = run_main(argv, capsys)
    assert code == 2 and "holds a finished run with residual None" in stderr
