"""RL Zoo itself reads the shipped configs: every entry through its own preprocessing, and ``python -m
rl_zoo3.train`` for a few hundred steps on one id of every family (as configs/ppo.yml's header tells users to run it).

PettingZoo swarms (``polyenvs.swarm.*``) are not Gymnasium ids and RL Zoo cannot make them; MaskablePPO is not one
of RL Zoo's algorithms, so maskable_ppo.yml goes through RL Zoo's preprocessing and sb3-contrib's constructor.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import gymnasium.envs.registration
import gymnasium.wrappers.common
import pytest

_TIME_LIMIT = gym.wrappers.TimeLimit
rl_zoo3 = pytest.importorskip("rl_zoo3", reason="rl_zoo3 is not installed (it is in the dev extra)")
# Importing rl_zoo3 replaces Gymnasium's TimeLimit process-wide (rl_zoo3.gym_patches adds "TimeLimit.truncated" to
# infos); this module only reads configs in-process and trains in subprocesses, so every other test gets Gymnasium's
# own wrapper back (pytest imports every test module before running any).
gym.wrappers.TimeLimit = gym.wrappers.common.TimeLimit = gym.envs.registration.TimeLimit = _TIME_LIMIT
yaml = pytest.importorskip("yaml")

import torch  # noqa: E402
from rl_zoo3.exp_manager import ExperimentManager  # noqa: E402
from rl_zoo3.utils import ALGOS  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402

import polyenvs  # noqa: E402,F401  (registers the ids, as --gym-packages polyenvs does)

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
#: Config file -> (RL Zoo's algorithm whose preprocessing reads it, the class that trains it).
FILES = {"ppo.yml": "ppo", "dqn.yml": "dqn", "sac.yml": "sac", "maskable_ppo.yml": "maskable_ppo"}


def _entries() -> list[tuple[str, str]]:
    return [
        (name, env_id)
        for name in sorted(FILES)
        for env_id in yaml.safe_load((CONFIGS / name).read_text())
        if env_id in gym.registry
    ]


def _algo_class(name: str):
    if FILES[name] == "maskable_ppo":
        from sb3_contrib import MaskablePPO

        return MaskablePPO
    return ALGOS[FILES[name]]


@pytest.mark.parametrize(("name", "env_id"), _entries(), ids=lambda v: str(v))
def test_rl_zoo_reads_every_entry_of_the_shipped_configs(name, env_id, tmp_path, capsys):
    """RL Zoo's ExperimentManager reads the entry, preprocesses it, makes its environment with its env_kwargs and
    builds the model with its hyperparameters (a string env_kwargs reached gym.make as a string)."""
    torch.set_num_threads(1)
    algo = "ppo" if FILES[name] == "maskable_ppo" else FILES[name]
    manager = ExperimentManager(argparse.Namespace(), algo, env_id, str(tmp_path), config=str(CONFIGS / name),
                                verbose=0)  # fmt: skip
    hyperparams, _ = manager.read_hyperparameters()
    hyperparams, _, _, _ = manager._preprocess_hyperparams(hyperparams)
    assert isinstance(manager.env_kwargs, dict), f"{name}: {env_id}: env_kwargs {manager.env_kwargs!r}"
    venv = make_vec_env(env_id, n_envs=1, env_kwargs=manager.env_kwargs)
    try:
        hyperparams.pop("buffer_size", None)  # SAC / DQN: allocating the replay buffer proves nothing here
        _algo_class(name)(env=venv, device="cpu", **hyperparams)
    finally:
        venv.close()
    capsys.readouterr()  # RL Zoo prints every hyperparameter


#: One Gymnasium id of every family: a Buckybot, a Platonic beast, the bump-only cart, a single-robot swarm id.
FAMILIES = ["polyenvs/BuckybotGoal-v0", "polyenvs/BeastRoll-v0", "polyenvs/BumperCartExplore-v0",
            "polyenvs/APLiteCorridor-v0"]  # fmt: skip


@pytest.mark.parametrize("env_id", FAMILIES)
def test_rl_zoo_trains_from_the_shipped_config(env_id, tmp_path):
    """The command configs/ppo.yml gives, shortened to 256 steps on one environment (about 10 s each)."""
    command = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", env_id, "--gym-packages", "polyenvs",
        "--conf-file", str(CONFIGS / "ppo.yml"), "-n", "256", "--hyperparams", "n_envs:1", "n_steps:64",
        "batch_size:64", "n_epochs:1", "-f", str(tmp_path / "logs"), "--eval-freq", "-1", "--seed", "0",
        "--num-threads", "1", "--device", "cpu", "--verbose", "0",
    ]  # fmt: skip
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
    }
    env.setdefault("MUJOCO_GL", "egl")
    done = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    slug = env_id.replace("/", "-")
    assert (tmp_path / "logs" / "ppo" / f"{slug}_1" / f"{slug}.zip").is_file(), done.stdout[-2000:]
