"""A batched swarm: E environments of N robots as one Gymnasium vector environment of E x N robots, for training
with parameter sharing (one policy acting on every robot's own observation), as SuperSuit's
``pettingzoo_env_to_vec_env_v1`` + ``concat_vec_envs_v1`` would give, but with one compiled call per kernel for
all E x N robots instead of one Python object per environment.

Rows: robot ``r`` of environment ``e`` is row ``e * N + r``. Environment ``e`` reset with seed ``s`` is the
PettingZoo environment reset with seed ``s + e``, bit for bit, through autoresets (its generator makes the same
draws in the same order: the episode, the drift, the first readings; then per step the wheels' and sensors'
normals and the IR floor), so every result can be checked against the single environment.

Robots that arrive leave their environment's episode as in PettingZoo; their rows then read zero observations
and zero rewards until the environment's episode ends (SuperSuit's "black death"). An environment's episode ends
when all its robots have left (every row terminated) or after ``max_cycles`` steps (rows still in the episode
truncated, rows that left terminated); it is then reset in the same step (``autoreset_mode`` SAME_STEP): the rows
show the new episode's first observation and ``info["final_obs"]`` the last one, and
``info["final_info"]["episode_metrics"]`` holds, on the rows of the environments that ended, their swarm metrics
(``SwarmEnv.episode_metrics``): Gymnasium's same-step convention, which SB3-style adapters translate.
"""

from __future__ import annotations

import importlib

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from polyenvs.core.validation import check_choice, check_int, check_options, real_array
from polyenvs.swarm import core
from polyenvs.swarm import sensors as ir
from polyenvs.swarm.env import (
    ARRIVED,
    COLLISIONS,
    DISTANCE,
    FORMATION_PENALTY,
    MAX_SPEED_FACTOR,
    MIN_CLEARANCE,
    N_TRACK,
    STILL,
    STOPPED_WINDOW_S,
    TIME_TO_GOAL,
    account,
)  # fmt: skip

__all__ = ["SwarmVectorEnv", "TASKS"]

TASKS = ("corridor_v0", "obstacle_field_v0", "formation_v0")
#: Unused obstacle slots: far away, radius 0 (never hit, never nearest).
_FAR = 1e6


class SwarmVectorEnv(VectorEnv):
    """``num_envs`` swarm environments of ``n_robots`` robots each, as ``num_envs * n_robots`` rows.

    Args:
        task: "corridor_v0", "obstacle_field_v0" or "formation_v0".
        num_envs: environments in the batch (1-65536).
        **kwargs: the task's keywords (``n_robots``, ``max_cycles``, noise, platform ...; no ``render_mode``).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, task: str = "corridor_v0", num_envs: int = 16, **kwargs):
        check_choice("task", task, TASKS)
        self.n_envs = check_int("num_envs", num_envs, 1, 65536)
        if kwargs.get("render_mode") is not None:
            raise ValueError("render_mode: the batched swarm does not render; render a single environment")
        self.task = importlib.import_module(f"polyenvs.swarm.{task}").parallel_env(**kwargs)
        t = self.task
        e, n = self.n_envs, t.n_robots
        self.n_robots = n
        self.num_envs = e * n
        self.single_observation_space = t.observation_space("robot_0")
        self.single_action_space = t.action_space("robot_0")
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.max_cycles = t.max_cycles
        rows = e * n
        self.pose = np.zeros((rows, 3))
        self.active = np.zeros(rows, dtype=np.uint8)
        self.circles = np.full((e, t.n_obstacles, 3), [_FAR, _FAR, 0.0])
        self.goals = np.zeros((e, 2))
        self.cycles = np.zeros(e, dtype=np.int64)
        self._grid = core.Grid(t.layout.bounds, t._cell_m, n, e)
        self._todo = np.ones(rows, dtype=np.uint8)
        self._proposal = np.zeros((rows, 3))
        self._blocked = np.zeros(rows, dtype=np.uint8)
        self._beams = np.zeros((rows, 4))
        self._nb_index = np.zeros((rows, t.n_neighbours), dtype=np.int64)
        self._nb_range = np.zeros((rows, t.n_neighbours))
        self._clearance = np.zeros(rows)
        self._powers = np.zeros((rows, 2))
        self._drift = np.zeros((rows, 2))
        self._track = np.zeros((rows, N_TRACK))
        self._rewards = np.zeros((rows, len(t.reward_names)))
        self._normals = np.zeros((e, n, 2 + t._sense_draws))
        self._floor = np.zeros((e, n, 4))
        self._obs = np.zeros((rows, t._obs_size), dtype=np.float32)
        if t.formation:
            self._per_robot = np.zeros(rows)
            self._pair_count = np.zeros(rows)
            self._swarm_error = np.zeros(e)
            self._formation_sum = np.zeros(rows)
            self._swarm_sum = np.zeros(e)
        self._generators: list[np.random.Generator | None] = [None] * e
        self._started = False  # step() needs a first reset()

    # --- Gymnasium VectorEnv API ------------------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        """Reset every environment; environment ``e`` gets seed ``seed + e`` (a list gives one seed per
        environment, or one per row, of which environment e takes row ``e * n_robots``'s). The swarm takes no
        reset options: ``options`` must be ``None`` or ``{}`` (anything else raises and changes nothing)."""
        check_options(options, ())
        e = self.n_envs
        if seed is None:
            seeds = [None] * e
        elif isinstance(seed, (list, tuple)):
            if len(seed) == self.num_envs:  # one per row (an SB3 adapter's): environment e takes its first row's
                seed = seed[:: self.n_robots]
            if len(seed) != e:
                raise ValueError(f"seed: {len(seed)} seeds for {e} environments ({self.num_envs} rows)")
            seeds = list(seed)
        else:
            seeds = [check_int("seed", seed, 0) + i for i in range(e)]
        self._generators = [seeding.np_random(s)[0] for s in seeds]
        self._reset_envs(np.arange(e))
        self._started = True
        return self._obs.copy(), {}

    def step(self, actions):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        t, e, n = self.task, self.n_envs, self.n_robots
        command = real_array("actions", actions)  # complex, bool, string and object input refused, not cast
        if command.shape != (self.num_envs, 2) or not (np.abs(command) <= 1.0).all():
            raise ValueError(f"actions must be an array of shape ({self.num_envs}, 2) in [-1, 1] without NaN")
        for g, normals, floor in zip(self._generators, self._normals, self._floor, strict=True):
            g.standard_normal(out=normals)
            g.random(out=floor)
        normals = self._normals.reshape(e * n, -1)
        command = command * self.active[:, None]
        noise = np.clip(1.0 + t.terrain_noise * normals[:, :2] + self._drift, 0.0, MAX_SPEED_FACTOR)
        wheels = command * t.full_speed_mps * noise
        before = self.pose.copy()
        grid = self._grid.arrays
        core.build_grid(self.pose, self.active, *grid)
        core.move(self.pose, self.active, wheels, t._move_params, t._walls, self.circles, *grid, self._proposal,
                  self._blocked)  # fmt: skip
        self.cycles += 1
        self._powers = command
        obs = self._observe(normals[:, 2:], self._floor.reshape(e * n, 4))
        terminated = np.zeros(e * n, dtype=np.uint8)
        account(self.pose, before, self.active, self._blocked, self._clearance, self.goals, n, self.cycles,
                t._account_params, self._track, self._rewards, terminated)  # fmt: skip
        if t.formation:
            self._score_formation()
        rewards = self._rewards.sum(axis=1)
        self.active[terminated > 0] = 0
        left = (self.active == 0).reshape(e, n)
        truncated_env = self.cycles >= self.max_cycles
        done_env = left.all(axis=1) | truncated_env
        infos = {}
        row_terminated = (left & done_env[:, None]).reshape(-1)
        row_truncated = (~left & truncated_env[:, None]).reshape(-1)
        if done_env.any():
            done = np.flatnonzero(done_env)
            rows = np.repeat(done_env, n)
            infos["final_obs"] = np.where(rows[:, None], obs, 0.0).astype(np.float32)
            infos["_final_obs"] = rows
            metrics = self._env_metrics()
            episode = {k: np.where(rows, np.repeat(v, n), 0.0) for k, v in metrics.items()}
            infos["final_info"] = {"episode_metrics": episode, "_episode_metrics": rows}
            infos["_final_info"] = rows
            self._reset_envs(done)
            obs = self._obs
        return obs.copy(), rewards, row_terminated, row_truncated, infos

    # --- internals --------------------------------------------------------------------------------------------
    def _observe(self, normals, floor) -> np.ndarray:
        t = self.task
        grid = self._grid.arrays
        core.build_grid(self.pose, self.active, *grid)
        core.sense(self.pose, self.active, self._todo, t._sense_params, t._angles, t._walls, self.circles, *grid,
                   self._beams, self._nb_index, self._nb_range, self._clearance)  # fmt: skip
        ir.write_observations(self.pose, self.active, self._beams, self._nb_index, self._nb_range, self.goals,
                              self.n_robots, self._powers, normals, floor, t._observe_params, t._leader_at,
                              self._obs)  # fmt: skip
        return self._obs

    def _reset_envs(self, envs: np.ndarray) -> None:
        """New episodes for ``envs``: drawn on each one's generator in the single environment's order."""
        t, n = self.task, self.n_robots
        sense_normals = np.zeros((self.n_envs * n, t._sense_draws))
        floor = np.zeros((self.n_envs * n, 4))
        self._todo[:] = 0
        for e in envs.tolist():
            g = self._generators[e]
            episode = t._sample_episode(g)
            rows = slice(e * n, (e + 1) * n)
            circles = np.asarray(episode.circles, dtype=np.float64).reshape(-1, 3)
            self.circles[e] = (_FAR, _FAR, 0.0)
            self.circles[e, : len(circles)] = circles
            self.goals[e] = episode.goal
            self.pose[rows] = episode.starts
            self.active[rows] = 1
            self._drift[rows] = t.terrain_noise * 0.5 * g.standard_normal((n, 2))
            sense_normals[rows] = g.standard_normal((n, t._sense_draws))
            floor[rows] = g.random((n, 4))
            self._powers[rows] = 0.0
            self._todo[rows] = 1
        self.cycles[envs] = 0
        previous = self._obs.copy()
        obs = self._observe(sense_normals, floor)
        reset_rows = self._todo > 0
        obs[~reset_rows] = previous[~reset_rows]
        self._track[reset_rows] = 0.0
        self._track[reset_rows, DISTANCE] = np.hypot(
            *(self.pose[reset_rows, :2] - np.repeat(self.goals, n, axis=0)[reset_rows]).T
        )
        self._track[reset_rows, MIN_CLEARANCE] = self._clearance[reset_rows]
        self._rewards[reset_rows] = 0.0
        if t.formation:
            self._formation_sum[reset_rows] = 0.0
            self._swarm_sum[envs] = 0.0
            self._score_formation(envs, reset_rows)
        self._todo[:] = 1

    def _score_formation(self, envs=None, rows=None) -> None:
        from polyenvs.swarm.formation_v0 import formation_error

        t = self.task
        formation_error(self.pose, self.active, t.pairs, t.spacing_m, self._per_robot, self._pair_count,
                        self._swarm_error)  # fmt: skip
        live = self.active > 0
        if envs is None:  # a step: the formation term, and the running sums
            self._rewards[:, 3] = np.where(live, -FORMATION_PENALTY * self._per_robot, 0.0)
            self._formation_sum += np.where(live, self._per_robot, 0.0)
            self._swarm_sum += self._swarm_error
        else:  # a reset: the first readings count, as in the single environment
            self._formation_sum[rows] = np.where(live[rows], self._per_robot[rows], 0.0)
            self._swarm_sum[envs] = self._swarm_error[envs]

    def _env_metrics(self) -> dict[str, np.ndarray]:
        """``SwarmEnv.episode_metrics`` of every environment, as arrays over environments."""
        t, n = self.task, self.n_robots
        track = self._track.reshape(self.n_envs, n, N_TRACK)
        window = max(1, round(STOPPED_WINDOW_S / t.control_period_s))
        metrics = {
            "success_rate": track[:, :, ARRIVED].mean(axis=1),
            "collisions": track[:, :, COLLISIONS].sum(axis=1),
            "time_to_goal_s": track[:, :, TIME_TO_GOAL].mean(axis=1),
            "min_clearance_cm": 100.0 * track[:, :, MIN_CLEARANCE].min(axis=1),
            "stopped": ((track[:, :, STILL] >= window) & (track[:, :, ARRIVED] == 0)).sum(axis=1).astype(np.float64),
        }
        if t.formation:
            metrics["formation_error"] = self._swarm_sum / (self.cycles + 1)
        return metrics
