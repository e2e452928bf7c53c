"""The batched swarm (E environments x N robots as one vector env) against the PettingZoo environment it batches."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.swarm import APLiteGoalSeeking, FormationController
from polyenvs.swarm import corridor_v0, formation_v0, obstacle_field_v0
from polyenvs.swarm.batch import TaskTerms
from polyenvs.swarm.batched import SwarmVectorEnv
from polyenvs.swarm.env import Episode, Layout, SwarmEnv
from polyenvs.swarm.layouts import box_walls

MODULES = {"corridor_v0": corridor_v0, "obstacle_field_v0": obstacle_field_v0, "formation_v0": formation_v0}


@pytest.mark.parametrize("task", list(MODULES))
def test_each_batched_environment_is_the_single_environment_bit_for_bit(task):
    """Environment e of the batch reset with seed s reproduces ``parallel_env`` reset with seed s + e: observations,
    rewards and episode ends, through autoresets (short episodes, so several happen)."""
    kwargs = {"n_robots": 3, "max_cycles": 25}
    if task == "corridor_v0":
        kwargs["max_cycles"] = 260  # long enough for robots to arrive and leave
    n_envs, steps, seed = 3, 300, 11
    batch = SwarmVectorEnv(task, num_envs=n_envs, **kwargs)
    singles = [MODULES[task].parallel_env(**kwargs) for _ in range(n_envs)]
    policy_cls = FormationController if task == "formation_v0" else APLiteGoalSeeking
    space = batch.single_observation_space
    policy = policy_cls(space, batch.single_action_space, platform=batch.task.platform.name, sensors=(0, 1, 2, 3))
    obs, _ = batch.reset(seed=seed)
    single_obs = [env.reset(seed=seed + e)[0] for e, env in enumerate(singles)]
    rng = np.random.default_rng(0)
    ends = arrivals = 0
    for _ in range(steps):
        for e, env in enumerate(singles):
            for a, o in single_obs[e].items():
                assert np.array_equal(obs[e * 3 + env.agent_name_mapping[a]], o)
        actions, _ = policy.predict(obs)
        actions = np.clip(actions + 0.05 * rng.standard_normal(actions.shape), -1, 1).astype(np.float32)
        obs, rewards, terminated, truncated, infos = batch.step(actions)
        for e, env in enumerate(singles):
            live = list(env.agents)
            step_obs, step_rewards, step_term, step_trunc, _ = env.step(
                {a: actions[e * 3 + env.agent_name_mapping[a]] for a in live}
            )
            for a in live:
                row = e * 3 + env.agent_name_mapping[a]
                assert rewards[row] == step_rewards[a]
                arrivals += step_term[a]
            if not env.agents:  # the episode ended: the batch has reset this environment in the same step
                ends += 1
                rows = slice(e * 3, e * 3 + 3)
                assert infos["_final_obs"][rows].all()
                for a, o in step_obs.items():
                    assert np.array_equal(infos["final_obs"][e * 3 + env.agent_name_mapping[a]], o)
                metrics = env.episode_metrics()
                for k, v in metrics.items():
                    assert infos["final_info"]["episode_metrics"][k][e * 3] == pytest.approx(v, rel=1e-12, abs=1e-12)
                assert (terminated[rows] | truncated[rows]).all()
                single_obs[e] = env.reset()[0]
            else:
                single_obs[e] = step_obs
                assert not (terminated[e * 3 : e * 3 + 3] | truncated[e * 3 : e * 3 + 3]).any()
    assert ends >= n_envs
    if task == "corridor_v0":
        assert arrivals > 0


def test_batched_rows_of_departed_robots_read_zero_and_bad_actions_raise():
    batch = SwarmVectorEnv("corridor_v0", num_envs=2, n_robots=2)
    obs, _ = batch.reset(seed=0)
    assert obs.shape == (4, batch.single_observation_space.shape[0]) and batch.observation_space.contains(obs)
    pose = batch.pose.copy()
    for bad in (np.full((4, 2), np.nan), np.zeros((3, 2)), np.full((4, 2), 1.5)):
        with pytest.raises(ValueError, match="actions"):
            batch.step(bad)
        assert np.array_equal(batch.pose, pose)
    batch.active[1] = 0  # robot 1 of environment 0 has left
    obs, rewards, *_ = batch.step(np.full((4, 2), 0.5, np.float32))
    assert not obs[1].any() and rewards[1] == 0.0 and obs[0].any()
    with pytest.raises(ValueError, match="task"):
        SwarmVectorEnv("pistonball", num_envs=2)
    with pytest.raises(ValueError, match="num_envs"):
        SwarmVectorEnv("corridor_v0", num_envs=0)


def test_batched_swarm_trains_with_ppo_through_the_native_adapter():
    """Parameter sharing at scale: the batched swarm as an SB3 VecEnv of robots (same-step autoreset), seeded."""
    sb3 = pytest.importorskip("stable_baselines3")
    import torch

    from polyenvs.training.vec_adapter import NativeVecEnvAdapter

    torch.set_num_threads(1)
    venv = NativeVecEnvAdapter(SwarmVectorEnv("corridor_v0", num_envs=4, n_robots=2, max_cycles=30))
    model = sb3.PPO("MlpPolicy", venv, n_steps=32, batch_size=128, n_epochs=1, seed=0, verbose=0)
    model.learn(512)
    assert model.num_timesteps >= 512
    venv.close()


class _ClockTerms(TaskTerms):
    """A task's own parts, declared by name: an observation part ``clock`` (steps into the episode / 100), a reward
    term ``still`` (-0.01 per step for every robot in the episode) and a metric ``steps``."""

    observation_parts = {"clock": (0.0,)}
    reward_names = ("still",)
    metric_names = ("steps",)

    def __init__(self, task, batch):
        super().__init__(task, batch)
        self.at, self.column = batch.structure["clock"][0], batch.reward_column("still")

    def observe(self, live, todo, normals, out):
        rows = (todo > 0) & (live > 0)
        out[rows, self.at] = (np.repeat(self.batch.cycles, self.batch.n_robots) / 100.0)[rows]

    def score(self, live, rows, envs):
        self.batch.rewards[:, self.column] = np.where(live, -0.01, 0.0)

    def env_metrics(self):
        return {"steps": self.batch.cycles.astype(np.float64)}

    def robot_metrics(self):
        return {"steps": np.repeat(self.batch.cycles, self.batch.n_robots).astype(np.float64)}


class _ClockRoom(SwarmEnv):
    """A task written outside the package: a 4 x 4 m room, one obstacle, the goal in a corner."""

    terms_class = _ClockTerms
    n_obstacles = 1

    def _fixed_layout(self):
        return Layout(walls=box_walls(0.0, 0.0, 4.0, 4.0), bounds=(0.0, 0.0, 4.0, 4.0))

    def sample_episode(self, rng):
        starts = np.column_stack([0.5 + 0.6 * np.arange(self.n_robots), np.full(self.n_robots, 0.5),
                                  rng.uniform(-np.pi, np.pi, self.n_robots)])  # fmt: skip
        return Episode(
            circles=np.array([[2.0, 2.0, 0.3 + 0.1 * rng.random()]]), starts=starts, goal=np.array([3.5, 3.5])
        )


def test_a_task_passed_as_a_class_adds_its_named_parts_to_both_forms_bit_for_bit():
    """The family's base knows no task: a task of its own (a class, here defined in the test) declares an
    observation part, a reward term and a metric by name, and the batch of 3 gives the PettingZoo env's episodes."""
    kwargs = {"n_robots": 2, "max_cycles": 15}
    batch = SwarmVectorEnv(_ClockRoom, num_envs=3, **kwargs)
    singles = [_ClockRoom(**kwargs) for _ in range(3)]
    assert batch.task.observation_structure["clock"] == (24, 25) and batch.task.reward_names[-1] == "still"
    obs, _ = batch.reset(seed=5)
    single_obs = [env.reset(seed=5 + e)[0] for e, env in enumerate(singles)]
    rng = np.random.default_rng(1)
    for _ in range(40):
        for e in range(3):
            assert all(np.array_equal(obs[2 * e + r], single_obs[e][f"robot_{r}"]) for r in range(2))
        actions = rng.uniform(-1, 1, (6, 2)).astype(np.float32)
        obs, rewards, _, _, infos = batch.step(actions)
        for e, env in enumerate(singles):
            step_obs, step_rewards, _, _, step_infos = env.step(
                {a: actions[2 * e + i] for i, a in enumerate(env.agents)}
            )
            assert [rewards[2 * e + r] for r in range(2)] == list(step_rewards.values())
            assert step_infos["robot_0"]["reward_still"] == -0.01
            assert ("episode_metrics" in step_infos["robot_0"]) == (not env.agents)  # the robot's last cycle only
            if not env.agents:  # truncated: the batch reset it in the same step
                assert "steps" in step_infos["robot_0"]["episode_metrics"]
                assert infos["final_info"]["episode_metrics"]["steps"][2 * e] == env.episode_metrics()["steps"] == 15
                step_obs = env.reset()[0]
            single_obs[e] = step_obs
        live = batch.active > 0
        assert np.array_equal(obs[live, 24], (np.repeat(batch.batch.cycles, 2) / 100.0).astype(np.float32)[live])


def test_a_task_instance_is_a_batch_of_its_own_parameters():
    kwargs = {"n_robots": 3, "max_cycles": 30}
    by_name = SwarmVectorEnv("formation_v0", num_envs=2, **kwargs)
    by_instance = SwarmVectorEnv(formation_v0.parallel_env(**kwargs), num_envs=2)
    by_class = SwarmVectorEnv(formation_v0.FormationEnv, num_envs=2, **kwargs)
    results = [env.reset(seed=3) for env in (by_name, by_instance, by_class)]
    rng = np.random.default_rng(2)
    for _ in range(40):
        actions = rng.uniform(-1, 1, (6, 2))
        results = [env.step(actions) for env in (by_name, by_instance, by_class)]
        for other in results[1:]:
            assert all(np.array_equal(a, b) for a, b in zip(results[0][:4], other[:4], strict=True))
    with pytest.raises(ValueError, match="task"):
        SwarmVectorEnv(formation_v0.parallel_env(), num_envs=2, n_robots=3)
    with pytest.raises(ValueError, match="task"):
        SwarmVectorEnv(object, num_envs=2)


@pytest.mark.parametrize("module", [corridor_v0, obstacle_field_v0])
def test_a_robots_info_row_is_its_row_of_the_info_columns(module):
    """The PettingZoo env's per-robot info (built as dictionaries from the info table) is robot i's row of
    ``robot_columns`` (what the vector envs report): the same keys in the same order, the same values, the same
    types (Python numbers, arrays for the vector keys), including a robot that has stopped (held at zero power) and
    robots in contact; and a robot's ``episode_metrics``, on its last cycle only, its row of the metric columns."""
    env = module.parallel_env(n_robots=3, max_cycles=80)
    env.reset(seed=4)
    rng = np.random.default_rng(0)
    seen_stopped, ended = False, 0
    for _ in range(80):
        actions = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}
        if "robot_2" in actions:
            actions["robot_2"] = np.zeros(2, np.float32)
        _, _, terminations, truncations, infos = env.step(actions)
        info, metrics = env.batch.robot_columns()
        for agent, row_info in infos.items():
            i = env.agent_name_mapping[agent]
            row_metrics = row_info.pop("episode_metrics", None)
            assert (row_metrics is not None) == (terminations[agent] or truncations[agent])
            ended += row_metrics is not None
            for columns, row in ((info, row_info), (metrics, row_metrics or {})):
                assert not row or list(row) == list(columns)
                for key, column in columns.items() if row else ():
                    expected = column[i] if column.ndim > 1 else column.tolist()[i]
                    if isinstance(expected, np.ndarray):
                        assert row[key].dtype == expected.dtype and np.array_equal(row[key], expected), key
                    else:
                        assert type(row[key]) is type(expected) and row[key] == expected, key
            seen_stopped |= row_info["stopped"]
    assert seen_stopped and ended == 3
