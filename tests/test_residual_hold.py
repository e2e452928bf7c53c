"""Held residuals (``ResidualPolicy(..., hold=k)``, ``train --residual-hold``): the agent decides every k control
ticks, its correction held while the baseline is re-run and recombined on every tick.

A step of the wrapper must be k steps of the environment with that composition; a zero correction must still be
the baseline's episode; and a loaded agent, called every tick on the environment as registered, must act exactly
as the wrapper it trained in made it act (its state keeps the held correction and the tick count).
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the ids)
from baselines import make_policy
from baselines.residual import ResidualPolicy, ResidualSpec
from baselines.trained import load_trained_policy
from polyenvs.evaluation.rollout import policy_action
from tests.cli_helpers import run_main
from tests.test_residual import _baseline_episode, _make

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

CORRIDOR, BEAST = "polyenvs/APLiteCorridor-v0", "polyenvs/BeastTumble-v1"


class _Recorded(gym.Wrapper):
    """Records every action the environment receives."""

    def __init__(self, env):
        super().__init__(env)
        self.actions: list[np.ndarray] = []

    def step(self, action):
        self.actions.append(np.array(action, copy=True))
        return self.env.step(action)


def _by_hand(env_id: str, corrections, hold: int, seed: int, scale: float = 0.5) -> tuple[list, list]:
    """What a held residual means, written out: each correction for ``hold`` ticks of the environment, the paper's
    policy re-run on every tick; ``(observations after each decision, summed rewards)``."""
    env = gym.make(env_id)
    base = make_policy("paper", env_id, env.observation_space, env.action_space, seed=0)
    obs, _ = env.reset(seed=seed)
    action, state = base.predict(obs, None, np.array([True]))
    observations, rewards = [], []
    for correction in corrections:
        total = None
        for _ in range(hold):
            combined = np.clip(action + scale * correction.astype(action.dtype), -1, 1).astype(action.dtype)
            obs, reward, terminated, truncated, _ = env.step(combined)
            total = reward if total is None else total + reward
            action, state = base.predict(obs, state, np.array([False]))
            if terminated or truncated:
                break
        observations.append(obs)
        rewards.append(total)
    return observations, rewards


@pytest.mark.parametrize("hold", [1, 3])
def test_a_step_of_the_wrapper_is_hold_ticks_of_the_composition(hold):
    corrections = np.random.default_rng(4).uniform(-1, 1, (60, 2)).astype(np.float32)
    wrapper = ResidualPolicy(gym.make(CORRIDOR), "paper", 0.5, hold=hold)
    obs, _ = wrapper.reset(seed=8)
    size = wrapper.env.observation_space.shape[0]
    ours = [wrapper.step(c) for c in corrections]
    observations, rewards = _by_hand(CORRIDOR, corrections, hold, 8)
    np.testing.assert_array_equal(np.array([o[0][:size] for o in ours]), np.array(observations))
    assert [o[1] for o in ours] == rewards


def _zero_held_episode(wrapper: ResidualPolicy, seed: int) -> dict:
    obs, _ = wrapper.reset(seed=seed)
    total, decisions = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = wrapper.step(np.zeros(wrapper.action_space.shape, np.float32))
        total, decisions = total + float(reward), decisions + 1
        if terminated or truncated:
            metrics = wrapper.unwrapped.episode_metrics()  # the TimeLimit truncates outside the env
            return {"return": total, "decisions": decisions, "metrics": metrics, "last": obs}


@pytest.mark.parametrize("env_id", [BEAST, CORRIDOR])
def test_a_zero_correction_held_for_5_ticks_is_the_papers_episode(env_id):
    wrapper = ResidualPolicy(_make(env_id), "paper", 0.1, hold=5)
    for seed in (31, 32):
        ours, theirs = _zero_held_episode(wrapper, seed), _baseline_episode(env_id, seed)
        assert ours["metrics"] == theirs["metrics"]
        assert ours["decisions"] == -(-theirs["length"] // 5)
        # The summed rewards add the ticks in another grouping: equal to rounding, not bit for bit.
        assert ours["return"] == pytest.approx(theirs["return"], rel=1e-9, abs=1e-9)


def _random_residual_agent(env_id: str, out, hold: int):
    """A residual agent's training directory with a nonzero network: the zeroed last layer given random weights."""
    import torch
    from stable_baselines3 import PPO

    from polyenvs.evaluation.episodes import resolve_env
    from polyenvs.training.residual import residual_wrapper, start_at_the_base
    from polyenvs.training.vec_adapter import make_training_vec_env

    spec = ResidualSpec("paper", 0.2, hold=hold)
    venv = make_training_vec_env(resolve_env(env_id), 1, seed=0, wrappers=[residual_wrapper(spec, env_id)])
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [16]})
    start_at_the_base(model, -3.0)
    venv.close()
    with torch.no_grad():
        generator = torch.Generator().manual_seed(hold)
        layer = model.policy.action_net
        layer.weight.copy_(0.1 * torch.randn(layer.weight.shape, generator=generator))  # not saturated at +-1
    out.mkdir(parents=True)
    model.save(out / "model.zip")
    (out / "run.json").write_text(json.dumps({"env_id": env_id, "algo": "ppo", "seed": 0, "residual": spec.to_json()}))
    return model, spec


def _wrapper_actions(env_id: str, model, spec: ResidualSpec, seeds, steps: int) -> list[list[np.ndarray]]:
    """Per episode, the environment's actions while the model drives the wrapper (its deterministic action)."""
    recorder = _Recorded(_make(env_id))
    wrapper = ResidualPolicy(recorder, spec.baseline, spec.scale, hold=spec.hold)
    episodes = []
    for seed in seeds:
        recorder.actions = []
        obs, _ = wrapper.reset(seed=seed)
        while len(recorder.actions) < steps:
            obs, _, terminated, truncated, _ = wrapper.step(model.predict(obs, deterministic=True)[0])
            if terminated or truncated:
                break
        episodes.append(recorder.actions[:steps])
    return episodes


def _loaded_actions(env_id: str, path, seeds, steps: int) -> list[list[np.ndarray]]:
    """The same with the loaded agent called every tick on the registered env, its state carried from one episode
    into the next (as a vector env's autoreset carries it), the next one marked by ``episode_start``."""
    recorder = _Recorded(_make(env_id))
    agent = load_trained_policy(path, env_id, recorder.observation_space, recorder.action_space)
    episodes, state = [], None
    for seed in seeds:
        recorder.actions = []
        obs, info = recorder.reset(seed=seed)
        start = True
        while len(recorder.actions) < steps:
            action, state = policy_action(agent, obs, state, start, info)
            obs, _, terminated, truncated, info = recorder.step(action)
            start = False
            if terminated or truncated:
                break
        episodes.append(recorder.actions)
    return episodes


@pytest.mark.parametrize(("env_id", "hold", "steps"), [(CORRIDOR, 5, 203), (BEAST, 5, 152), (CORRIDOR, 1, 60)])
def test_a_loaded_held_agent_acts_on_the_registered_env_as_in_its_wrapper(env_id, hold, steps, tmp_path):
    """Episodes cut at a length that is not a multiple of the hold: the next one must start a fresh count."""
    model, spec = _random_residual_agent(env_id, tmp_path / "agent", hold)
    seeds = (41, 42)
    ours = _wrapper_actions(env_id, model, spec, seeds, steps)
    theirs = _loaded_actions(env_id, tmp_path / "agent", seeds, steps)
    for episode_ours, episode_theirs in zip(ours, theirs, strict=True):
        assert len(episode_ours) == len(episode_theirs) == steps
        np.testing.assert_array_equal(np.array(episode_ours), np.array(episode_theirs))
    # The network is not zero: the agent's actions are not the paper's.
    recorder = _Recorded(_make(env_id))
    paper = make_policy("paper", env_id, recorder.observation_space, recorder.action_space)
    obs, info = recorder.reset(seed=seeds[0])
    state = None
    for start in [True] + [False] * 29:
        action, state = policy_action(paper, obs, state, start, info)
        obs, *_, info = recorder.step(action)
    assert not np.array_equal(np.array(recorder.actions), np.array(theirs[0][:30]))


@pytest.mark.parametrize("hold", [0, -1, 101, 2.5, True, "5", None])
def test_a_bad_hold_raises_naming_hold(hold):
    with pytest.raises(ValueError, match="hold"):
        ResidualPolicy(gym.make(CORRIDOR), hold=hold)
    with pytest.raises(ValueError, match="hold"):
        ResidualSpec(hold=hold)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--residual", "paper", "--residual-hold", "0"], "--residual-hold must be >= 1"),
        (["--residual", "paper", "--residual-hold", "101"], "--residual-hold must be <= 100"),
        (["--residual", "paper", "--residual-hold", "2.5"], "--residual-hold must be an integer"),
        (["--residual-hold", "5"], "need --residual NAME"),
    ],
)
def test_bad_hold_flags_are_one_line_before_training(flags, message, tmp_path, capsys, monkeypatch):
    import polyenvs.training.vec_adapter as adapter

    monkeypatch.setattr(adapter, "make_training_vec_env", lambda *a, **k: pytest.fail("work started"))
    argv = ["train", CORRIDOR, *flags, "--algo", "ppo", "--out", str(tmp_path / "x")]
    code, _, stderr = run_main(argv, capsys)
    assert code == 2 and message in stderr and len(stderr.strip().splitlines()) == 1


def test_train_records_the_hold_and_evaluate_holds_as_trained(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["train", CORRIDOR, "--algo", "ppo", "--residual", "paper", "--residual-hold", "4", "--residual-log-std",
            "-2", "--timesteps", "128", "--n-envs", "2", "--out", str(out), "--no-progress"]  # fmt: skip
    code, _, stderr = run_main(argv, capsys)
    assert code == 0, stderr
    run = json.loads((out / "run.json").read_text())
    assert run["residual"]["hold"] == 4 and run["completed"] is True
    code, stdout, stderr = run_main(["evaluate", CORRIDOR, "--policy", str(out), "--episodes", "1", "--json"], capsys)
    assert code == 0, stderr
    assert json.loads(stdout)["policy_description"]["residual"]["hold"] == 4
    # Another hold is another run: a finished directory of hold 4 is not taken for a run of hold 1.
    argv = ["train", CORRIDOR, "--algo", "ppo", "--residual", "paper", "--out", str(out), "--no-progress"]
    code, _, stderr = run_main(argv, capsys)
    assert code == 2 and "holds a finished run with residual" in stderr


def test_a_run_recorded_before_hold_existed_loads_with_hold_1():
    assert ResidualSpec.from_json({"baseline": "paper", "scale": 0.3, "observe_base": True}).hold == 1
