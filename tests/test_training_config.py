"""RL Zoo-format configs: the shipped files cover every id and load; parsing is safe; errors name file and key."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("sb3_contrib")
yaml = pytest.importorskip("yaml")

import gymnasium as gym  # noqa: E402
from stable_baselines3.common.utils import LinearSchedule  # noqa: E402
from torch import nn  # noqa: E402

import polyenvs  # noqa: E402
from polyenvs.errors import InputError  # noqa: E402
from polyenvs.training.config import jsonable, load_config, parse_python_value  # noqa: E402

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
ALGO_OF_FILE = {
    "ppo.yml": "ppo",
    "ppo_residual.yml": "ppo",
    "ppo_bc.yml": "ppo",
    "ppo_stack.yml": "ppo",
    "maskable_ppo.yml": "maskable_ppo",
    "dqn.yml": "dqn",
    "sac.yml": "sac",
}
WALL = "polyenvs/BuckybotWallFollow-v0"


def _discrete_ids() -> list[str]:
    ids = []
    for env_id in polyenvs.ENV_IDS:
        env = gym.make(env_id)
        if isinstance(env.action_space, gym.spaces.Discrete):
            ids.append(env_id)
        env.close()
    return ids


def test_every_config_file_is_known():
    assert sorted(p.name for p in CONFIGS.glob("*.yml")) == sorted(ALGO_OF_FILE)


@pytest.mark.parametrize("name", sorted(ALGO_OF_FILE))
def test_every_key_is_a_registered_id_and_every_entry_loads(name):
    document = yaml.safe_load((CONFIGS / name).read_text())
    for env_id in document:
        assert env_id in polyenvs.registry.ALL_IDS, f"configs/{name}: {env_id} is not a registered polyenvs id"
        config = load_config(CONFIGS / name, env_id, ALGO_OF_FILE[name])
        assert config.policy == "MlpPolicy"
        net_arch = config.hyperparams["policy_kwargs"]["net_arch"]
        widths = [w for part in (net_arch.values() if isinstance(net_arch, dict) else [net_arch]) for w in part]
        assert 0 < len(widths) <= 4 and max(widths) <= 256, f"{name}: {env_id}: not a small MLP: {net_arch}"
        if config.algo in ("ppo", "maskable_ppo"):
            rollout = config.hyperparams["n_steps"] * config.n_envs
            assert rollout % config.hyperparams["batch_size"] == 0, f"{name}: {env_id}: minibatches do not fit"


def test_every_id_has_ppo_with_normalize_and_every_discrete_id_has_maskable_ppo():
    ppo = yaml.safe_load((CONFIGS / "ppo.yml").read_text())
    masked = yaml.safe_load((CONFIGS / "maskable_ppo.yml").read_text())
    for env_id in polyenvs.registry.ALL_IDS:
        assert env_id in ppo, f"configs/ppo.yml has no entry for {env_id}"
        assert "normalize" in ppo[env_id], f"configs/ppo.yml: {env_id} does not say whether to normalize"
    for env_id in _discrete_ids():
        assert env_id in masked, f"configs/maskable_ppo.yml has no entry for {env_id}"


def test_configs_state_the_rl_zoo_command():
    text = (CONFIGS / "ppo.yml").read_text() + (CONFIGS / "README.md").read_text()
    assert (
        "python -m rl_zoo3.train --algo ppo --env polyenvs/BuckybotWallFollow-v0 --gym-packages polyenvs "
        "--conf-file configs/ppo.yml" in text
    )


# ---------------------------------------------------------------------------------------------------- parsing


def _write(tmp_path: Path, entry: dict, env_id: str = WALL) -> Path:
    path = tmp_path / "conf.yml"
    path.write_text(yaml.safe_dump({env_id: entry}))
    return path


BASE = {"n_timesteps": 1000, "policy": "MlpPolicy"}


def test_rl_zoo_values_are_resolved(tmp_path):
    path = tmp_path / "conf.yml"
    path.write_text(
        f"""
{WALL}:
  n_timesteps: !!float 1e5
  policy: 'MlpPolicy'
  n_envs: 4
  normalize: "{{'norm_obs': True, 'norm_reward': False}}"
  learning_rate: lin_3.0e-4
  clip_range: lin_0.2
  gamma: 0.98
  n_steps: 128
  max_grad_norm: 1
  normalize_advantage: false
  policy_kwargs: "dict(net_arch=dict(pi=[32, 32], vf=[64]), activation_fn=nn.Tanh, ortho_init=False,
    log_std_init=-2, optimizer_class=th.optim.RMSprop, optimizer_kwargs=dict(eps=1e-5))"
"""
    )
    config = load_config(path, WALL, "ppo")
    assert config.n_timesteps == 100_000 and isinstance(config.n_timesteps, int)
    assert config.n_envs == 4
    assert config.normalize is True
    assert config.normalize_kwargs == {"norm_obs": True, "norm_reward": False, "gamma": 0.98}  # gamma as RL Zoo
    lr = config.hyperparams["learning_rate"]
    assert isinstance(lr, LinearSchedule)
    assert lr(1.0) == pytest.approx(3e-4) and lr(0.5) == pytest.approx(1.5e-4) and lr(0.0) == 0.0
    assert config.hyperparams["clip_range"](0.25) == pytest.approx(0.05)
    assert config.hyperparams["max_grad_norm"] == 1.0 and config.hyperparams["normalize_advantage"] is False
    import torch

    assert config.hyperparams["policy_kwargs"] == {
        "net_arch": {"pi": [32, 32], "vf": [64]},
        "activation_fn": nn.Tanh,
        "ortho_init": False,
        "log_std_init": -2,
        "optimizer_class": torch.optim.RMSprop,
        "optimizer_kwargs": {"eps": 1e-5},
    }
    resolved = config.resolved()
    assert resolved["learning_rate"] == "lin_3.0e-4"
    assert resolved["policy_kwargs"]["activation_fn"] == "torch.nn.Tanh"
    assert resolved["policy_kwargs"]["optimizer_class"] == "torch.optim.RMSprop"
    assert resolved["normalize"] == {"norm_obs": True, "norm_reward": False, "gamma": 0.98}
    import json

    json.dumps(resolved)  # JSON-able


def test_normalize_forms(tmp_path):
    for value, expected in [
        (True, (True, {})),
        (False, (False, {})),
        ("dict(norm_obs=False, norm_reward=True)", (True, {"norm_obs": False, "norm_reward": True})),
        ({"norm_obs": True, "clip_obs": 5}, (True, {"norm_obs": True, "clip_obs": 5.0})),
    ]:
        config = load_config(_write(tmp_path, {**BASE, "normalize": value}), WALL, "ppo")
        assert (config.normalize, config.normalize_kwargs) == expected
        # run.json's record: VecNormalize's arguments in full (never an empty, falsy dict), or False
        resolved = config.resolved()["normalize"]
        assert resolved == ({"norm_obs": True, "norm_reward": True, **expected[1]} if expected[0] else False)


def test_env_wrapper_forms(tmp_path):
    config = load_config(
        _write(tmp_path, {**BASE, "env_wrapper": "gymnasium.wrappers.FlattenObservation"}), WALL, "ppo"
    )
    assert config.env_wrappers == [("gymnasium.wrappers.FlattenObservation", {})]
    config = load_config(
        _write(
            tmp_path,
            {**BASE, "env_wrapper": [{"gymnasium.wrappers.TimeLimit": {"max_episode_steps": 10}}, "gymnasium.Wrapper"]},
        ),
        WALL,
        "ppo",
    )
    assert config.env_wrappers == [
        ("gymnasium.wrappers.TimeLimit", {"max_episode_steps": 10}),
        ("gymnasium.Wrapper", {}),
    ]
    env = gym.make(WALL)
    for wrap in config.wrapper_callables():
        env = wrap(env)
    assert env.get_wrapper_attr("_max_episode_steps") == 10


def test_dqn_train_freq_and_ints(tmp_path):
    config = load_config(
        _write(tmp_path, {**BASE, "train_freq": [4, "episode"], "buffer_size": 1e4, "exploration_fraction": 0.1}),
        WALL,
        "dqn",
    )
    assert config.hyperparams["train_freq"] == (4, "episode")
    assert config.hyperparams["buffer_size"] == 10_000 and isinstance(config.hyperparams["buffer_size"], int)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({**BASE, "n_step": 64}, "n_step: unknown key for ppo (PPO) (did you mean 'n_steps'?)"),
        ({**BASE, "exploration_fraction": 0.1}, "exploration_fraction: unknown key for ppo"),
        ({**BASE, "seed": 3}, "seed: unknown key"),  # set by train, not the config
        ({**BASE, "callback": "x.Y"}, "callback: training callbacks from the config are not supported"),
        ({"policy": "MlpPolicy"}, "n_timesteps: missing"),
        ({**BASE, "n_timesteps": "1e6"}, "n_timesteps: expected an integer >= 1, got '1e6' (YAML reads it as text"),
        ({**BASE, "n_timesteps": 0}, "n_timesteps: expected an integer >= 1, got 0"),
        ({**BASE, "n_envs": 2.5}, "n_envs: expected an integer >= 1, got 2.5"),
        ({**BASE, "n_envs": True}, "n_envs: expected an integer >= 1, got True"),
        ({**BASE, "policy": "LstmPolicy"}, "policy: expected one of MlpPolicy, CnnPolicy, MultiInputPolicy for PPO"),
        ({**BASE, "learning_rate": "3e-4"}, "learning_rate: expected a number or 'lin_<number>'"),
        ({**BASE, "learning_rate": "cos_0.1"}, "learning_rate: expected a number or 'lin_<number>'"),
        ({**BASE, "learning_rate": "lin_abc"}, "learning_rate: expected a number or 'lin_<number>'"),
        ({**BASE, "gamma": "0.99x"}, "gamma: expected a finite number, got '0.99x'"),
        ({**BASE, "gamma": ".nan"}, "gamma: expected a finite number"),
        ({**BASE, "use_sde": 1}, "use_sde: expected true or false, got 1"),
        ({**BASE, "n_steps": 64.5}, "n_steps: expected an integer"),
        ({**BASE, "normalize": "yes"}, "normalize: the name 'yes' is not allowed"),
        ({**BASE, "normalize": 1}, "normalize: expected true, false or a dict"),
        ({**BASE, "normalize": "{'norm_obs': 1}"}, "normalize: norm_obs must be True or False"),
        ({**BASE, "normalize": "{'norm_rewards': True}"}, "normalize: unknown VecNormalize argument 'norm_rewards'"),
        ({**BASE, "policy_kwargs": "dict(net_arch=[64, 64]"}, "policy_kwargs: not a Python expression"),
        ({**BASE, "policy_kwargs": "[64, 64]"}, "policy_kwargs: expected a dict"),
        ({**BASE, "policy_kwargs": "dict(net_arch=__import__('os'))"}, "policy_kwargs: the call __import__(...)"),
        ({**BASE, "policy_kwargs": "dict(f=os.system)"}, "policy_kwargs: the name 'os.system' is not allowed"),
        (
            {**BASE, "policy_kwargs": "dict(f=nn.functional)"},
            "policy_kwargs: nn.functional is not a torch.nn.Module class",
        ),
        ({**BASE, "policy_kwargs": "dict(f=th.optim.lr_scheduler)"}, "is not a torch.optim.Optimizer class"),
        ({**BASE, "policy_kwargs": "dict(f=torch.nn.modules.Tanh)"}, "the name 'torch.nn.modules.Tanh' is not allowed"),
        ({**BASE, "policy_kwargs": "dict(f=nn.Nope)"}, "policy_kwargs: nn.Nope is not a torch.nn.Module class"),
        ({**BASE, "policy_kwargs": "dict(a=1 + 2)"}, "policy_kwargs: the expression '1 + 2' is not allowed"),
        ({**BASE, "policy_kwargs": "dict(**x)"}, "policy_kwargs: '**' unpacking is not allowed"),
        ({**BASE, "policy_kwargs": "{1: 2}"}, "policy_kwargs: the non-string key 1 is not allowed"),
        ({**BASE, "policy_kwargs": "dict(a=[x for x in y])"}, "is not allowed"),
        ({**BASE, "env_wrapper": "no_such_module.Wrapper"}, "env_wrapper: cannot import no_such_module.Wrapper"),
        ({**BASE, "env_wrapper": "Wrapper"}, "env_wrapper: expected an import path 'module.Name'"),
        ({**BASE, "env_wrapper": 3}, "env_wrapper: expected an import path"),
        ({**BASE, "env_wrapper": "gymnasium.__version__"}, "env_wrapper: gymnasium.__version__ is not a class"),
    ],
)
def test_config_errors_name_file_id_and_key(tmp_path, entry, message):
    path = _write(tmp_path, entry)
    with pytest.raises(InputError) as info:
        load_config(path, WALL, "ppo")
    text = str(info.value)
    assert text.startswith(f"{path}: {WALL}: "), text
    assert message in text, text
    assert "\n" not in text


def test_file_errors(tmp_path):
    with pytest.raises(InputError, match=r"config file .*missing\.yml does not exist"):
        load_config(tmp_path / "missing.yml", WALL, "ppo")
    bad = tmp_path / "bad.yml"
    bad.write_text(f"{WALL}:\n  n_steps: [1, 2\n")
    with pytest.raises(InputError, match=r"bad\.yml: not valid YAML: .*\(line \d+, column \d+\)"):
        load_config(bad, WALL, "ppo")
    listing = tmp_path / "list.yml"
    listing.write_text("- 1\n- 2\n")
    with pytest.raises(InputError, match="expected a mapping of environment ids"):
        load_config(listing, WALL, "ppo")
    other = _write(tmp_path, BASE, env_id="polyenvs/BuckybotGoal-v0")
    with pytest.raises(InputError, match=f"has no entry for {WALL} \\(it has: polyenvs/BuckybotGoal-v0\\)"):
        load_config(other, WALL, "ppo")
    scalar = tmp_path / "scalar.yml"
    scalar.write_text(f"{WALL}: 3\n")
    with pytest.raises(InputError, match="expected a mapping of hyperparameters"):
        load_config(scalar, WALL, "ppo")
    with pytest.raises(InputError, match="unknown algorithm 'a2c'"):
        load_config(_write(tmp_path, BASE), WALL, "a2c")


def test_parse_python_value_allows_only_data_and_torch_classes():
    assert parse_python_value("dict(a=[1, -2.5, 'x'], b=(True, None), c={'d': nn.ReLU})") == {
        "a": [1, -2.5, "x"],
        "b": (True, None),
        "c": {"d": nn.ReLU},
    }
    assert parse_python_value("torch.nn.SiLU") is nn.SiLU
    assert parse_python_value("th.nn.ELU") is nn.ELU
    for text in ("open('x')", "nn.Tanh()", "().__class__", "lambda: 1", "nn.Tanh.__init__", "f'{x}'", "-'a'", "b'x'"):
        with pytest.raises(InputError):
            parse_python_value(text)


def test_jsonable():
    assert jsonable({"a": (nn.Tanh, 1), "b": [None, True, "s"]}) == {"a": ["torch.nn.Tanh", 1], "b": [None, True, "s"]}


def test_env_kwargs_are_a_yaml_mapping_as_rl_zoo_needs_them(tmp_path):
    """RL Zoo hands env_kwargs to the environment as they are (a string made it fail with ``make_env() argument
    after ** must be a mapping, not str``): the reader takes the same form, and no other."""
    entry = {"n_timesteps": 100, "policy": "MlpPolicy", "env_kwargs": {"floor_plan": "office", "noise_scale": 0.5}}
    config = load_config(_write(tmp_path, entry), WALL, "ppo")
    assert config.env_kwargs == {"floor_plan": "office", "noise_scale": 0.5}
    assert config.resolved()["env_kwargs"] == {"floor_plan": "office", "noise_scale": 0.5}
    entry["env_kwargs"] = "dict(floor_plan='corner')"
    with pytest.raises(InputError, match=r"env_kwargs: write env_kwargs as a YAML mapping .*RL Zoo passes it on as"):
        load_config(_write(tmp_path, entry), WALL, "ppo")
    for bad in ([1, 2], 3, {1: 2}):
        entry["env_kwargs"] = bad
        with pytest.raises(InputError, match="env_kwargs: expected a mapping of keyword arguments"):
            load_config(_write(tmp_path, entry), WALL, "ppo")


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        # RL Zoo evaluates the strings of policy_kwargs and replay_buffer_kwargs only
        ({**BASE, "rollout_buffer_kwargs": "dict(gae_lambda=0.9)"}, "write rollout_buffer_kwargs as a YAML mapping"),
        (
            {**BASE, "env_wrapper": [{"gymnasium.wrappers.TimeLimit": "dict(max_episode_steps=10)"}]},
            "write the keyword arguments of gymnasium.wrappers.TimeLimit as a YAML mapping",
        ),
        # RL Zoo calls Wrapper(env, **kwargs): no keyword arguments is an empty mapping, or the bare path
        ({**BASE, "env_wrapper": [{"gymnasium.wrappers.TimeLimit": None}]}, "expected {'module.Wrapper': {kwargs}}"),
        # RL Zoo splits a schedule at its one "_"
        ({**BASE, "learning_rate": "lin_1_000"}, "learning_rate: expected a number or 'lin_<number>'"),
    ],
)
def test_only_the_forms_rl_zoo_reads(tmp_path, entry, message):
    with pytest.raises(InputError, match=re.escape(message)):
        load_config(_write(tmp_path, entry), WALL, "ppo")


def test_the_shipped_configs_write_every_env_kwargs_as_a_mapping():
    for path in sorted(CONFIGS.glob("*.yml")):
        for env_id, entry in yaml.safe_load(path.read_text()).items():
            if "env_kwargs" in entry:
                assert isinstance(entry["env_kwargs"], dict), f"{path.name}: {env_id}: env_kwargs is not a mapping"
