"""Training configs in RL Zoo's format, and Stable-Baselines3 training on every environment (a few hundred steps)."""

from __future__ import annotations

from pathlib import Path

import pytest

import polyenvs

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
RL_ZOO_KEYS = {
    "n_envs", "n_timesteps", "policy", "n_steps", "batch_size", "gae_lambda", "gamma", "n_epochs", "ent_coef",
    "learning_rate", "clip_range", "policy_kwargs", "normalize", "env_wrapper", "buffer_size", "learning_starts",
    "target_update_interval", "train_freq", "gradient_steps", "exploration_fraction", "exploration_final_eps",
    "vf_coef", "max_grad_norm",
}  # fmt: skip


@pytest.mark.parametrize("algo", ["ppo", "dqn"])
def test_configs_cover_every_discrete_id(algo):
    yaml = pytest.importorskip("yaml")
    config = yaml.safe_load((CONFIGS / f"{algo}.yml").read_text())
    for env_id in polyenvs.ENV_IDS:
        assert env_id in config, f"configs/{algo}.yml has no entry for {env_id}"
        assert set(config[env_id]) <= RL_ZOO_KEYS
        assert config[env_id]["policy"] == "MlpPolicy"


@pytest.mark.parametrize("env_id", polyenvs.ENV_IDS)
def test_ppo_trains_a_few_steps(env_id):
    torch = pytest.importorskip("torch")
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(1)  # two threads on these 2-core machines are intermittently 10-100x slower
    venv = make_vec_env(env_id, n_envs=2, seed=0)
    model = sb3.PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (2,)


def test_maskable_ppo_uses_the_action_mask():
    torch = pytest.importorskip("torch")
    contrib = pytest.importorskip("sb3_contrib")
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
