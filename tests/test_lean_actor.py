"""The lean inference path of a trained policy (``baselines.trained.LeanActor``) acts exactly as Stable-Baselines3's
deterministic ``predict``: the same actions bit for bit, dtype and shape, on the committed agents of every kind it
takes (gSDE with observation normalisation on the beasts, a categorical action on Buckybot, MaskablePPO's masked
one, a Box on the cart, a batch of robots on the swarm), along their own trajectories; and a policy it does not
repeat keeps SB3's predict.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from baselines.trained import LeanActor  # noqa: E402
from polyenvs.evaluation.episodes import make_agent, make_env  # noqa: E402
from polyenvs.evaluation.protocol import old_versions_quietly  # noqa: E402
from polyenvs.evaluation.rollout import is_parallel  # noqa: E402

AGENTS = Path(__file__).resolve().parents[1] / "benchmarks" / "agents"
STEPS = 200


def sb3_predict(agent, observation, masks=None):
    """The action SB3's own predict gives (the wrapper's path without the lean actor)."""
    lean, agent.lean = agent.lean, None
    try:
        return agent.predict(observation, deterministic=True, action_masks=masks)[0]
    finally:
        agent.lean = lean


def assert_same(lean_action, sb3_action):
    assert lean_action.dtype == sb3_action.dtype and lean_action.shape == sb3_action.shape
    assert np.array_equal(lean_action, sb3_action)


def observations(env, agent, steps):
    """The observations (one robot batch per cycle, for a swarm) and action masks (for MaskablePPO) met acting
    with the lean actor from seed 1000."""
    if is_parallel(env):
        obs, _ = env.reset(seed=1000)
        for _ in range(steps):
            if not env.agents:
                return
            batch = np.stack([obs[a] for a in env.agents])
            yield batch, None
            actions = agent.lean(batch)
            obs, *_ = env.step({a: actions[i] for i, a in enumerate(env.agents)})
        return
    obs, info = env.reset(seed=1000)
    for _ in range(steps):
        masks = info["action_mask"].astype(bool) if agent.uses_action_masks else None
        yield obs, masks
        obs, _, terminated, truncated, info = env.step(agent.lean(obs, masks))
        if terminated or truncated:
            obs, info = env.reset()


@pytest.mark.parametrize(
    "env_id, agent_dir",
    [
        ("polyenvs/BeastRoll-v0", "polyenvs__BeastRoll-v0/ppo/seed0"),
        ("polyenvs/BuckybotWallFollow-v0", "polyenvs__BuckybotWallFollow-v0/ppo_bc_wall_follower_rules/seed0"),
        ("polyenvs/BuckybotExplore-v0", "polyenvs__BuckybotExplore-v0/maskable_ppo/seed0"),
        ("polyenvs/BumperCartExplore-v0", "polyenvs__BumperCartExplore-v0/ppo/seed0"),
        ("polyenvs.swarm.formation_v0", "polyenvs.swarm.formation_v0/ppo/seed0"),
    ],
)
def test_lean_actor_gives_sb3_predicts_actions_bit_for_bit(env_id, agent_dir):
    if env_id.startswith("polyenvs/Beast"):
        pytest.importorskip("mujoco")
    with old_versions_quietly():
        env = make_env(env_id)
    try:
        agent = make_agent(str(AGENTS / agent_dir), env_id, env)
        assert agent.lean is not None
        for obs, masks in observations(env, agent, STEPS):
            assert_same(agent.lean(obs, masks), sb3_predict(agent, obs, masks))
    finally:
        env.close()


def test_a_batch_of_one_stays_a_batch_and_a_bad_shape_is_refused():
    env = make_env("polyenvs/BuckybotWallFollow-v0")
    try:
        agent = make_agent(
            str(AGENTS / "polyenvs__BuckybotWallFollow-v0/ppo_bc_wall_follower_rules/seed0"),
            "polyenvs/BuckybotWallFollow-v0",
            env,
        )
        obs, _ = env.reset(seed=1000)
        assert_same(agent.lean(obs[None]), sb3_predict(agent, obs[None]))
        with pytest.raises(ValueError, match="observation of shape"):
            agent.lean(np.concatenate([obs, obs]))
    finally:
        env.close()


def test_a_policy_it_does_not_repeat_keeps_sb3s_predict():
    from stable_baselines3 import SAC

    env = make_env("polyenvs/BumperCartExplore-v0")
    try:
        assert LeanActor.for_model(SAC("MlpPolicy", env, seed=0, device="cpu")) is None
    finally:
        env.close()
