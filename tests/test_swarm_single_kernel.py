"""A single robot is not a swarm of one (issue 33): the AP-lite ids step one robot in one compiled call, bit for bit
the robot of the PettingZoo swarm of one; and the swarm family's lean ``info``."""

from __future__ import annotations

import hashlib

import gymnasium as gym
import numpy as np
import pytest

from polyenvs.core.episode_metrics import RecordEpisodeMetrics
from polyenvs.swarm import corridor_v0, obstacle_field_v0
from polyenvs.swarm.single import APLiteCorridorEnv, APLiteObstacleFieldEnv

CASES = [(APLiteCorridorEnv, corridor_v0), (APLiteObstacleFieldEnv, obstacle_field_v0)]
IDS = ["polyenvs/APLiteCorridor-v0", "polyenvs/APLiteObstacleField-v0"]


class _Digest:
    """A running SHA-256 of a rollout's outputs: arrays by bytes, numbers by type and ``repr`` (so -0.0 differs
    from 0.0 and an int from a float), dicts key by key in order."""

    def __init__(self):
        self.hash = hashlib.sha256()

    def add(self, value) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                self.hash.update(key.encode())
                self.add(item)
        elif isinstance(value, np.ndarray):
            self.hash.update(str(value.dtype).encode() + value.tobytes())
        else:
            self.hash.update(f"{type(value).__name__}:{value!r}".encode())


def _actions(seed: int, steps: int) -> np.ndarray:
    """Seeded float32 actions: half random, half straight ahead (so robots both wander and arrive)."""
    rng = np.random.default_rng(seed)
    random = rng.uniform(-1, 1, (steps, 2)).astype(np.float32)
    return np.where(rng.random((steps, 1)) < 0.5, random, np.float32(0.7))


def _single_rollout(env, seeds, steps: int) -> str:
    digest = _Digest()
    for seed in seeds:
        for episode, actions in enumerate((_actions(seed, steps), _actions(seed + 100, steps))):
            obs, info = env.reset(seed=seed if episode == 0 else None)  # the second: the generator continues
            digest.add(obs)
            digest.add(info)
            for action in actions:
                obs, reward, terminated, truncated, info = env.step(action)
                info = dict(info)
                metrics = info.pop("episode_metrics", None)
                assert (metrics is not None) == (terminated or truncated)
                for part in (obs, reward, terminated, truncated, info):
                    digest.add(part)
                if terminated or truncated:
                    digest.add(metrics)
                    break
            digest.add(env.episode_metrics())
    return digest.hash.hexdigest()


def _swarm_rollout(swarm, seeds, steps: int) -> str:
    """The same rollout through the PettingZoo swarm of one robot, reported as the single env reports it."""
    digest = _Digest()
    for seed in seeds:
        for episode, actions in enumerate((_actions(seed, steps), _actions(seed + 100, steps))):
            obs, infos = swarm.reset(seed=seed if episode == 0 else None)
            digest.add(obs["robot_0"])
            digest.add(infos["robot_0"])
            for action in actions:
                obs, rewards, terminations, truncations, infos = swarm.step({"robot_0": action})
                info = dict(infos["robot_0"])
                metrics = info.pop("episode_metrics", None)
                ended = terminations["robot_0"] or truncations["robot_0"]
                parts = (obs["robot_0"], rewards["robot_0"], terminations["robot_0"], truncations["robot_0"], info)
                for part in parts:
                    digest.add(part)
                if ended:
                    digest.add(metrics)
                    break
            digest.add({name: float(value[0]) for name, value in swarm.batch.robot_metrics().items()})
    return digest.hash.hexdigest()


@pytest.mark.parametrize("layouts", ["default", "test"])
@pytest.mark.parametrize(("single_class", "module"), CASES, ids=["corridor", "obstacle_field"])
def test_the_single_robot_step_is_the_swarm_of_ones_robot_bit_for_bit(single_class, module, layouts):
    """Long seeded rollouts (robots that wander, collide, stop and arrive; unseeded resets that continue the
    generator) hash the same through the single env's one compiled call as through the PettingZoo swarm of one."""
    kwargs = {"layouts": layouts}
    single = single_class(**kwargs)
    swarm = module.parallel_env(n_robots=1, max_cycles=150, **kwargs)
    single.swarm.max_cycles = 150  # the same own cap, so that both truncate where the swarm does
    seeds = (0, 1, 2)
    assert _single_rollout(single, seeds, 400) == _swarm_rollout(swarm, seeds, 400)


@pytest.mark.parametrize("env_id", IDS)
def test_the_native_vector_env_rows_are_the_single_env(env_id):
    """Row i of ``gym.make_vec`` is ``gym.make`` seeded s + i through autoresets (the lean metrics on the rows
    that end, time limit included, as ``RecordEpisodeMetrics`` adds them to the single env's last info)."""
    num_envs, steps = 3, 260
    vector = gym.make_vec(env_id, num_envs=num_envs, max_episode_steps=120)
    singles = [RecordEpisodeMetrics(gym.make(env_id, max_episode_steps=120)) for _ in range(num_envs)]
    obs, _ = vector.reset(seed=7)
    single_obs = [env.reset(seed=7 + i)[0] for i, env in enumerate(singles)]
    restart = np.zeros(num_envs, dtype=bool)
    actions = np.stack([_actions(i, steps) for i in range(num_envs)], axis=1)
    ended = 0
    for t in range(steps):
        assert np.array_equal(obs, np.stack(single_obs))
        obs, rewards, terminated, truncated, info = vector.step(actions[t])
        for i, env in enumerate(singles):
            if restart[i]:  # next-step autoreset: this step only restarts the row
                single_obs[i] = env.reset()[0]
                continue
            single_obs[i], reward, done, cut, single_info = env.step(actions[t, i])
            assert (reward, done, cut) == (rewards[i], terminated[i], truncated[i])
            assert np.array_equal(info["pose"][i], single_info["pose"])
            if done or cut:
                ended += 1
                vector_metrics = {k: v[i] for k, v in info["episode_metrics"].items() if not k.startswith("_")}
                assert vector_metrics == single_info["episode_metrics"] and info["_episode_metrics"][i]
            else:
                assert "episode_metrics" not in info or not info["_episode_metrics"][i]
        restart = terminated | truncated
    assert ended >= num_envs


@pytest.mark.parametrize("single_class", [APLiteCorridorEnv, APLiteObstacleFieldEnv])
def test_the_single_env_reports_its_metrics_on_its_last_step_and_on_demand(single_class):
    env = single_class()
    with pytest.raises(gym.error.ResetNeeded):
        env.episode_metrics()
    _, info = env.reset(seed=3)
    assert "episode_metrics" not in info and env.episode_metrics()["time_to_goal_s"] == 0.0
    env.swarm.pose[0, :2] = env.swarm.goal  # at the light: the next step arrives
    _, _, terminated, _, info = env.step(np.zeros(2, np.float32))
    assert terminated and info["episode_metrics"] == env.episode_metrics()
    assert info["episode_metrics"]["success_rate"] == 1.0
    # A step's arrays are its own: a later step does not change what an earlier one handed over.
    env.reset(seed=3)
    first = env.step(np.full(2, 0.5, np.float32))[4]
    pose = first["pose"].copy()
    env.step(np.full(2, 0.5, np.float32))
    assert np.array_equal(first["pose"], pose)


def test_a_swarm_robot_reports_its_metrics_on_the_cycle_it_leaves_and_the_views_are_read_only():
    env = corridor_v0.parallel_env(n_robots=3, max_cycles=30)
    _, infos = env.reset(seed=0)
    assert all("episode_metrics" not in info for info in infos.values())
    env.batch.pose[1, :2] = env.goal  # robot_1 arrives at the next cycle: its metrics then, the others' not yet
    _, _, terminations, _, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert terminations == {"robot_0": False, "robot_1": True, "robot_2": False}
    assert [("episode_metrics" in info) for info in infos.values()] == [False, True, False]
    assert infos["robot_1"]["episode_metrics"]["success_rate"] == 1.0
    pose = infos["robot_0"]["pose"]
    assert np.shares_memory(pose, env.pose) and not pose.flags.writeable  # a view made once, valid for a step
    with pytest.raises(ValueError, match="read-only"):
        pose[0] = 0.0
    while env.agents:
        _, _, _, truncations, infos = env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert all(truncations.values()) and all("episode_metrics" in info for info in infos.values())
    assert set(infos) == {"robot_0", "robot_2"}
