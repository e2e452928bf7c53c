"""TorchRL's wrappers build every polyenvs environment as they are (skipped where torchrl is not installed).

``GymEnv`` probes a constructor with ``frameskip=`` and catches Python's own unknown-keyword ``TypeError``; any other
error, or wording, stops it."""

from __future__ import annotations

import pytest

import polyenvs

torchrl_gym = pytest.importorskip("torchrl.envs.libs.gym", reason="torchrl is not installed (it is in the dev extra)")


@pytest.mark.parametrize("env_id", polyenvs.ENV_IDS)
def test_torchrl_gym_env_makes_and_rolls_out(env_id):
    env = torchrl_gym.GymEnv(env_id)
    rollout = env.rollout(5)
    assert rollout.batch_size[0] >= 1
    assert rollout["next", "observation"].isfinite().all()
    env.close()
