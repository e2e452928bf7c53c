"""Stable-Baselines3 on every environment, and ``polyenvs.training.train``: a few hundred steps into a run directory.

The configs themselves are tested in ``test_training_config.py``, the VecEnv adapter in ``test_training_adapter.py``
and the ``polyenvs train`` command in ``test_training_command.py``.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pytest

import polyenvs

torch = pytest.importorskip("torch")
sb3 = pytest.importorskip("stable_baselines3")
contrib = pytest.importorskip("sb3_contrib")

from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402

from polyenvs.errors import InputError  # noqa: E402
from polyenvs.training.train import TrainingInterrupted, TrainRequest, train  # noqa: E402

WALL = "polyenvs/BuckybotWallFollow-v0"
CONFIGS = Path(__file__).resolve().parents[1] / "configs"
RUN_KEYS = {
    "env_id", "algo", "seed", "timesteps", "requested_timesteps", "n_envs", "env_kwargs", "hyperparams", "command",
    "versions", "git_commit", "wall_clock_s", "completed",
}  # fmt: skip


@pytest.mark.parametrize("env_id", polyenvs.ENV_IDS)
def test_ppo_trains_a_few_steps(env_id):
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(1)  # two threads on these 2-core machines are intermittently 10-100x slower
    venv = make_vec_env(env_id, n_envs=2, seed=0)
    model = sb3.PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (2, *venv.action_space.shape)


def test_maskable_ppo_uses_the_action_mask():
    import gymnasium as gym

    torch.set_num_threads(1)
    env = gym.make("polyenvs/BuckybotWallFollow-v0", floor_plan="corner")
    model = contrib.MaskablePPO("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=128)
    obs, info = env.reset(seed=0, options={"pose": (20.0, 110.0, 60.0)})
    assert info["action_mask"].tolist() == [1, 0, 1]
    for _ in range(20):
        action, _ = model.predict(obs, action_masks=env.unwrapped.action_masks())
        assert action != 1


# ------------------------------------------------------------------------------------------- polyenvs train


def _run(out: Path) -> dict:
    return json.loads((out / "run.json").read_text())


@pytest.mark.parametrize(("algo", "cls"), [("ppo", sb3.PPO), ("maskable_ppo", contrib.MaskablePPO)])
def test_train_writes_the_run_directory(tmp_path, algo, cls):
    out = tmp_path / "run"
    result = train(TrainRequest(
        WALL, algo, config=CONFIGS / f"{algo}.yml", timesteps=256, n_envs=2, seed=3, out_dir=out,
        env_kwargs={"floor_plan": "corner", "max_episode_steps": 50}, layouts="default", command="polyenvs train test",
    ))  # fmt: skip
    assert result == out
    assert {p.name for p in out.iterdir()} == {"model.zip", "vecnormalize.pkl", "run.json", "curve.json", "tb"}
    assert list((out / "tb").rglob("events.out.tfevents.*"))
    run = _run(out)
    assert RUN_KEYS <= set(run)
    assert run["env_id"] == WALL and run["algo"] == algo and run["seed"] == 3
    assert run["requested_timesteps"] == 256 and run["timesteps"] == 512  # one rollout: n_steps 256 x 2 envs
    assert run["n_envs"] == 2 and run["env_kwargs"] == {
        "floor_plan": "corner",
        "max_episode_steps": 50,
        "layouts": "default",
    }
    assert run["completed"] is True and run["wall_clock_s"] > 0
    assert run["command"] == "polyenvs train test"
    assert run["vec_env"] == "NativeVecEnvAdapter"
    assert set(run["versions"]) == {"python", "polyenvs", "gymnasium", "stable_baselines3", "sb3_contrib", "torch",
                                    "numpy"}  # fmt: skip
    assert run["git_commit"] is None or len(run["git_commit"]) == 40
    hyper = run["hyperparams"]
    assert hyper["policy"] == "MlpPolicy" and hyper["n_envs"] == 2 and hyper["n_timesteps"] == 256
    assert hyper["normalize"] == {"norm_obs": True, "norm_reward": True, "gamma": 0.99} and hyper["policy_kwargs"] == {
        "net_arch": [64, 64]
    }
    assert set(run["episode_metrics"]) >= {"perimeter_fraction"}  # 50-step episodes finished
    # The model loads back and acts; the normalisation statistics load back.
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    model = cls.load(out / "model.zip", device="cpu")
    assert model.num_timesteps == 512
    import gymnasium as gym

    stats = VecNormalize.load(str(out / "vecnormalize.pkl"), DummyVecEnv([lambda: gym.make(WALL)]))
    obs = stats.normalize_obs(stats.reset())
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (1,)


def test_train_logs_the_task_metrics_to_tensorboard(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = train(
        TrainRequest(
            WALL, "ppo", timesteps=256, n_envs=2, out_dir=tmp_path / "run", env_kwargs={"max_episode_steps": 20}
        )
    )
    (events,) = (out / "tb").rglob("events.out.tfevents.*")
    acc = EventAccumulator(str(events.parent))
    acc.Reload()
    tags = set(acc.Tags()["scalars"])
    assert {"rollout/ep_rew_mean", "episode_metrics/perimeter_fraction"} <= tags, tags


def test_train_rerun_skips_a_finished_run_and_refuses_other_directories(tmp_path):
    out = tmp_path / "run"
    kwargs = {"timesteps": 64, "n_envs": 1, "tensorboard": False}
    train(TrainRequest(WALL, "dqn", out_dir=out, seed=1, **kwargs))
    before = (out / "model.zip").stat().st_mtime_ns, (out / "run.json").read_text()
    assert train(TrainRequest(WALL, "dqn", out_dir=out, seed=1, **kwargs)) == out  # finished: nothing to do
    assert ((out / "model.zip").stat().st_mtime_ns, (out / "run.json").read_text()) == before
    with pytest.raises(InputError, match="holds a finished run of polyenvs/BuckybotWallFollow-v0 dqn seed 1"):
        train(TrainRequest(WALL, "dqn", out_dir=out, seed=2, **kwargs))
    with pytest.raises(InputError, match="holds a finished run"):
        train(TrainRequest(WALL, "ppo", out_dir=out, seed=1, **kwargs))
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds files and no run.json; choose another --out or remove it"):
        train(TrainRequest(WALL, "dqn", out_dir=other, **kwargs))
    (tmp_path / "file").write_text("")
    with pytest.raises(InputError, match="is a file"):
        train(TrainRequest(WALL, "dqn", out_dir=tmp_path / "file", **kwargs))
    empty = tmp_path / "empty"
    empty.mkdir()
    assert train(TrainRequest(WALL, "dqn", out_dir=empty, **kwargs)) == empty  # an empty directory is fine


class _Interrupt(BaseCallback):
    """Ctrl-C after ``after`` calls to step."""

    def __init__(self, after: int):
        super().__init__()
        self.after = after

    def _on_step(self) -> bool:
        if self.n_calls >= self.after:
            raise KeyboardInterrupt
        return True


def test_ctrl_c_saves_the_partial_model(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(TrainingInterrupted) as info:
        train(TrainRequest(
            WALL, "ppo", timesteps=100_000, n_envs=2, out_dir=out, callbacks=[_Interrupt(after=300)],
            tensorboard=False,
        ))  # fmt: skip
    assert isinstance(info.value, KeyboardInterrupt)
    assert info.value.out_dir == out and info.value.timesteps == 600  # 300 steps of 2 envs
    run = _run(out)
    assert run["completed"] is False and run["timesteps"] == 600 and run["requested_timesteps"] == 100_000
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()
    assert sb3.PPO.load(out / "model.zip", device="cpu").num_timesteps == 600
    # An interrupted run is not finished: a re-run refuses the directory instead of skipping it, and says how to go on.
    with pytest.raises(InputError, match=r"holds an interrupted run \(600 of 100000 timesteps saved\); --resume"):
        train(TrainRequest(WALL, "ppo", timesteps=64, n_envs=2, out_dir=out))


def test_resume_continues_the_saved_model_and_its_statistics(tmp_path):
    out = tmp_path / "run"
    common = {"n_envs": 2, "out_dir": out, "tensorboard": False}
    with pytest.raises(TrainingInterrupted):
        train(TrainRequest(WALL, "ppo", timesteps=100_000, callbacks=[_Interrupt(after=300)], **common))
    with pytest.raises(InputError, match="cannot resume .*: it trained with n_envs=2, this run asks for 4"):
        train(TrainRequest(WALL, "ppo", timesteps=1200, resume=True, **{**common, "n_envs": 4}))
    assert train(TrainRequest(WALL, "ppo", timesteps=1200, resume=True, **common)) == out
    run = _run(out)
    assert run["completed"] is True and run["resumed_at"] == [600] and run["timesteps"] >= 1200
    model = sb3.PPO.load(out / "model.zip", device="cpu")
    assert model.num_timesteps == run["timesteps"]
    with open(out / "vecnormalize.pkl", "rb") as fh:
        statistics = pickle.load(fh)
    # The statistics went on from the saved ones: one observation per env and step (and reset) since the start.
    assert abs(statistics.obs_rms.count - run["timesteps"]) <= 8
    # The learning curve goes on from the interrupted run's rows: no gap, no repeat, the task metrics beside the return.
    curve = json.loads((out / "curve.json").read_text())
    steps = curve["timesteps"]
    assert steps == sorted(set(steps)) and steps[0] <= 600 < steps[-1] <= run["timesteps"]
    assert len(curve["return"]) == len(steps) and "perimeter_fraction" in curve["metrics"]
    assert all(len(values) == len(steps) for values in curve["metrics"].values())


def test_native_and_dummy_training_give_the_same_model(tmp_path):
    """The adapter gives DummyVecEnv's experience bit for bit, so PPO learns the same weights on either."""
    common = {"timesteps": 256, "n_envs": 2, "seed": 4, "tensorboard": False, "env_kwargs": {"max_episode_steps": 30}}
    a = train(TrainRequest(WALL, "ppo", out_dir=tmp_path / "native", vec_env="native", **common))
    b = train(TrainRequest(WALL, "ppo", out_dir=tmp_path / "dummy", vec_env="dummy", **common))
    assert _run(a)["vec_env"] == "NativeVecEnvAdapter" and _run(b)["vec_env"] == "DummyVecEnv"
    params_a = sb3.PPO.load(a / "model.zip", device="cpu").policy.state_dict()
    params_b = sb3.PPO.load(b / "model.zip", device="cpu").policy.state_dict()
    for key in params_a:
        assert torch.equal(params_a[key], params_b[key]), key


def test_action_space_mismatch_and_bad_arguments(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(InputError, match=r"sac needs continuous actions \(Box\), but .* has Discrete\(3\); "
                       r"algorithms that fit: ppo, dqn, maskable_ppo"):  # fmt: skip
        train(TrainRequest(WALL, "sac", config=CONFIGS / "ppo.yml", out_dir=out))
    with pytest.raises(InputError, match="unknown algorithm 'a2c'; expected one of ppo, dqn, maskable_ppo, sac, td3"):
        train(TrainRequest(WALL, "a2c", out_dir=out))
    with pytest.raises(InputError, match="unknown environment id 'polyenvs/Nope-v0'"):
        train(TrainRequest("polyenvs/Nope-v0", "ppo", out_dir=out))
    with pytest.raises(InputError, match="timesteps must be >= 1"):
        train(TrainRequest(WALL, "ppo", timesteps=0, out_dir=out))
    with pytest.raises(InputError, match="seed must be an integer"):
        train(TrainRequest(WALL, "ppo", seed=1.5, out_dir=out))
    with pytest.raises(InputError, match="bad environment keyword arguments .*floor_plan"):
        train(TrainRequest(WALL, "ppo", env_kwargs={"floor_plan": "nowhere"}, out_dir=out))
    bad = tmp_path / "bad.yml"
    bad.write_text(f"{WALL}:\n  n_timesteps: 100\n  batch_size: 1\n")
    with pytest.raises(InputError, match=r"bad\.yml: polyenvs/BuckybotWallFollow-v0: PPO rejected the hyper"):
        train(TrainRequest(WALL, "ppo", config=bad, out_dir=out))
    assert not out.exists()  # nothing was written for any of these


def test_sac_trains_on_a_continuous_env(tmp_path):
    """The continuous algorithms work end to end (on Pendulum until a polyenvs family has continuous actions)."""
    config = tmp_path / "sac.yml"
    config.write_text("Pendulum-v1:\n  n_timesteps: 200\n  policy: 'MlpPolicy'\n  learning_starts: 50\n"
                      "  normalize: \"{'norm_obs': True, 'norm_reward': False}\"\n"
                      "  policy_kwargs: \"dict(net_arch=[16, 16])\"\n")  # fmt: skip
    out = train(TrainRequest("Pendulum-v1", "sac", config=config, out_dir=tmp_path / "run", tensorboard=False))
    run = _run(out)
    assert run["completed"] and run["timesteps"] == 200 and run["vec_env"] == "DummyVecEnv"
    assert run["hyperparams"]["normalize"] == {"norm_obs": True, "norm_reward": False}
    model = sb3.SAC.load(out / "model.zip", device="cpu")
    assert model.predict(np.zeros(3, dtype=np.float32))[0].shape == (1,)
    with pytest.raises(InputError, match="dqn needs discrete actions"):
        train(TrainRequest("Pendulum-v1", "dqn", config=config, out_dir=tmp_path / "dqn"))
