"""The swarm's one core: E environments of N robots, stepped, reset, scored and measured together.

:class:`SwarmBatch` is what every swarm surface runs on, at batch size 1 (the PettingZoo environment of
:mod:`polyenvs.swarm.env`) or E (the vector envs of :mod:`polyenvs.swarm.batched` and :mod:`polyenvs.swarm.vector`),
so the step, the reset, the rewards and the metrics exist once. A step is one noise draw per environment and one
compiled call per kernel for all E x N robots (:mod:`polyenvs.swarm.core`: grid, move, sense;
:func:`polyenvs.swarm.sensors.write_observations`; :func:`account`), plus what the task adds.

Rows: robot ``r`` of environment ``e`` is row ``e * N + r``. Every environment has its own generator and draws in
one fixed order, at a reset the episode (the task's ``sample_episode``), the wheels' drift and the first readings'
noise, then at each step the wheels' and sensors' normals and the IR floor; so environment ``e`` reset with
generator ``g`` is, bit for bit, a batch of one reset with ``g``, whatever the other environments do.

What a task adds to the family (the formation's leader, its reward term and metric) it declares by name in a
:class:`TaskTerms` subclass, which the batch builds with itself and calls at each observation, step and reset: the
core knows no task.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from polyenvs.core import generators as compiled_draws
from polyenvs.core.jit import njit
from polyenvs.swarm import core
from polyenvs.swarm import sensors as ir

__all__ = [
    "BEAM_M",
    "LIGHT_REFERENCE_M",
    "MAX_SPEED_FACTOR",
    "METRIC_NAMES",
    "REWARD_NAMES",
    "STILL_M",
    "STOPPED_WINDOW_S",
    "SwarmBatch",
    "TASK_NORMALS",
    "TaskTerms",
    "account",
    "drive",
]

#: GP2D12 reach (Sharp data sheet): beyond it the reading is the noise floor.
BEAM_M = ir.IR_MAX_CM / 100.0
#: Intensity of the goal light is 1 / (1 + (d / LIGHT_REFERENCE_M)^2) (inverse square, *ours*).
LIGHT_REFERENCE_M = 1.0
#: A robot that has moved less than this per step for STOPPED_WINDOW_S counts as stopped.
STILL_M = 1e-3
STOPPED_WINDOW_S = 1.0
#: Reward weights (*ours*): per metre of progress, per step in contact, on arrival.
PROGRESS_PER_M = 10.0
COLLISION_PENALTY = 1.0
ARRIVAL_BONUS = 10.0
#: The wheels' speed factor under terrain noise is clipped to [0, MAX_SPEED_FACTOR].
MAX_SPEED_FACTOR = 1.5
#: Unused obstacle slots: far away, radius 0 (never hit, never nearest).
FAR_M = 1e6

#: The family's reward terms (``info["reward_<name>"]``), in the columns :func:`account` writes.
REWARD_NAMES = ("progress", "collision", "arrival")
PROGRESS, COLLISION, ARRIVAL = range(3)
#: The family's episode metrics (per robot in ``info["episode_metrics"]``, per environment in ``episode_metrics()``).
METRIC_NAMES = ("success_rate", "collisions", "time_to_goal_s", "min_clearance_cm", "stopped")
#: Standard normals per robot per step that the family draws for the task's own observation parts (the formation's
#: leader bearing and range), after its own 9 + 2k: every task draws them, so every task's stream has one layout.
TASK_NORMALS = 2

#: Columns of the per-robot bookkeeping array ``SwarmBatch.track``.
DISTANCE, TURN, STILL, COLLISIONS, WAS_BLOCKED, ARRIVED, TIME_TO_GOAL, MIN_CLEARANCE = range(8)
N_TRACK = 8


@njit(cache=True)
def drive(command, live, noise, params, out):
    """The step's motor powers and wheel speeds: the ``(N, 2)`` power fractions ``command`` of the ``live``
    robots (0 for the others), times full speed, times each wheel's speed factor under terrain noise, ``1 +
    terrain_noise x normal + drift`` clipped to [0, MAX_SPEED_FACTOR].

    Args:
        noise: ``(normals, drift)``: the step's draws (the first two columns are the wheels') and the episode's
            per-wheel drift ``(N, 2)``.
        params: ``[terrain_noise, full_speed_mps]``.
        out: ``(powers, wheels)``, ``(N, 2)`` each, written.
    """
    normals, drift = noise
    powers, wheels = out
    terrain, full_speed = params[0], params[1]
    for i in range(command.shape[0]):
        for w in range(2):
            # Not command * live: a negative command times 0 is -0.0, and a robot out of its step (an environment
            # restarting, a robot that has left) reports the +0.0 power of its reset, as a fresh environment does.
            power = command[i, w] if live[i] else 0.0
            factor = min(max(1.0 + terrain * normals[i, w] + drift[i, w], 0.0), MAX_SPEED_FACTOR)
            powers[i, w] = power
            wheels[i, w] = power * full_speed * factor


@njit(cache=True)
def account(pose, before, active, sensed, episode, params, out):  # noqa: PLR0917 - numba kernel: arguments passed positionally, in its compiled signature's order
    """Score one step for every active robot: the family's reward terms (columns ``PROGRESS``, ``COLLISION``,
    ``ARRIVAL``), arrival and termination, and the running episode metrics in ``track`` (turn, still steps, contact
    events, time, smallest clearance).

    Args:
        before: ``(N, 3)`` poses before the step.
        sensed: ``(blocked, clearance)`` from :func:`polyenvs.swarm.core.move` and :func:`~polyenvs.swarm.core.sense`.
        episode: ``(goals, per, cycles)``: ``(E, 2)`` each environment's goal, robots per environment, ``(E,)``
            steps so far in each environment's episode.
        params: ``[goal_radius_m, dt_s, terminate_on_collision, still_m]``.
        out: ``(track, rewards, terminated)``, written.
    """
    blocked, clearance = sensed
    goals, per, cycles = episode
    track, rewards, terminated = out
    goal_radius, dt, stop_on_contact, still_m = params[0], params[1], params[2] > 0.5, params[3]
    for i in range(pose.shape[0]):
        terminated[i] = 0
        rewards[i, PROGRESS] = 0.0
        rewards[i, COLLISION] = 0.0
        rewards[i, ARRIVAL] = 0.0
        track[i, TURN] = 0.0
        if not active[i]:
            continue
        turn = pose[i, 2] - before[i, 2]
        track[i, TURN] = math.atan2(math.sin(turn), math.cos(turn))
        moved = math.hypot(pose[i, 0] - before[i, 0], pose[i, 1] - before[i, 1])
        track[i, STILL] = track[i, STILL] + 1.0 if moved < still_m else 0.0
        contact = blocked[i] > 0
        if contact and track[i, WAS_BLOCKED] == 0.0:
            track[i, COLLISIONS] += 1.0
        track[i, WAS_BLOCKED] = 1.0 if contact else 0.0
        e = i // per
        distance = math.hypot(pose[i, 0] - goals[e, 0], pose[i, 1] - goals[e, 1])
        arrived = distance <= goal_radius
        rewards[i, PROGRESS] = PROGRESS_PER_M * (track[i, DISTANCE] - distance)
        rewards[i, COLLISION] = -COLLISION_PENALTY if contact else 0.0
        rewards[i, ARRIVAL] = ARRIVAL_BONUS if arrived else 0.0
        track[i, DISTANCE] = distance
        if arrived:
            track[i, ARRIVED] = 1.0
        track[i, TIME_TO_GOAL] = cycles[e] * dt
        track[i, MIN_CLEARANCE] = min(track[i, MIN_CLEARANCE], clearance[i])
        terminated[i] = 1 if arrived or (contact and stop_on_contact) else 0


class TaskTerms:
    """What a task adds to the family, declared by name, and computed for a whole batch. The family's own tasks
    add nothing (this class); the formation adds its leader, a reward term and a metric
    (:class:`polyenvs.swarm.formation_v0.FormationTerms`). A task names its subclass in ``terms_class``.

    Class attributes:
        observation_parts: name -> the lower bounds of its columns (every upper bound is 1), placed in this order
            between ``neighbours`` and ``powers``.
        reward_names: reward terms after the family's (each in ``info["reward_<name>"]``, written by :meth:`score`
            into their :meth:`SwarmBatch.reward_column`).
        metric_names: episode metrics after the family's (:meth:`env_metrics`, :meth:`robot_metrics`).
        info_names: per-robot info keys after the family's (:meth:`robot_info`; both in
            :meth:`SwarmBatch.robot_columns`).

    Masks below are ``None`` (every row, every environment) or boolean arrays over rows and environments.
    """

    observation_parts: dict[str, tuple[float, ...]] = {}
    reward_names: tuple[str, ...] = ()
    metric_names: tuple[str, ...] = ()
    info_names: tuple[str, ...] = ()

    def __init__(self, task, batch: SwarmBatch):
        self.batch = batch

    def observe(self, live: np.ndarray, todo: np.ndarray, normals: np.ndarray, out: np.ndarray) -> None:
        """Write the task's observation parts of the rows in ``todo`` into ``out`` (the family has zeroed them);
        ``normals`` are the sensors' draws, whose last ``TASK_NORMALS`` columns are the task's; ``live`` marks the
        robots in the episode."""

    def score(self, live: np.ndarray, rows, envs) -> None:
        """After a step of the ``rows`` of ``envs`` (``live``: the robots that took it): the task's reward terms
        and running sums."""

    def restart(self, rows, envs) -> None:
        """After a reset of ``envs`` (their ``rows``): the sums start again, with the first readings."""

    def env_metrics(self) -> dict[str, np.ndarray]:
        """The task's episode metrics per environment, ``(E,)`` each."""
        return {}

    def robot_metrics(self) -> dict[str, np.ndarray]:
        """The task's episode metrics per robot, ``(E * N,)`` each (fresh arrays)."""
        return {}

    def robot_info(self) -> dict[str, np.ndarray]:
        """The task's info values per robot, ``(E * N, ...)`` each (fresh arrays)."""
        return {}


class SwarmBatch:
    """E environments of N robots of one swarm task, as ``E * N`` rows (see the module docstring).

    Args:
        task: the task (a :class:`polyenvs.swarm.env.SwarmEnv`): its validated parameters, ``layout``,
            ``n_obstacles``, ``observation_structure``, ``reward_names``, ``draw_episode(rng)`` and
            ``terms_class``.
        n_envs: environments in the batch.

    State (read by the surfaces; rows as above): ``pose`` ``(E * N, 3)``, ``active`` (robots in the episode),
    ``circles`` ``(E, n_obstacles, 3)`` (unused slots far away), ``n_circles``, ``goals`` ``(E, 2)``, ``cycles``
    ``(E,)`` (steps into each episode), ``generators`` (each environment's), ``observations``, ``rewards``
    (reward terms by column, :meth:`reward_column`), ``beams``, ``clearance``, ``powers``, ``track``.
    """

    def __init__(self, task, n_envs: int = 1):
        self.task = task
        n, e = task.n_robots, n_envs
        self.n_envs, self.n_robots, self.n_rows = e, n, e * n
        self.structure = task.observation_structure
        self.reward_names = tuple(task.reward_names)
        self._reward_keys = tuple(f"reward_{name}" for name in self.reward_names)
        self.sense_draws = 9 + 2 * task.n_neighbours + TASK_NORMALS
        self._constants(task)
        self._allocate(task)
        self.terms = task.terms_class(task, self)

    def _constants(self, task) -> None:
        """The kernels' parameters, from the task's validated ones."""
        radius = task.platform.radius_m
        self.terrain_noise = task.terrain_noise
        self.stopped_window = max(1, round(STOPPED_WINDOW_S / task.control_period_s))
        self.angles = np.radians(np.array(task.sensor_angles_deg))
        self.walls = np.ascontiguousarray(task.layout.walls, dtype=np.float64)[None]
        cell = core.cell_size(radius, BEAM_M, task.comm_range_m, task.max_step_m)
        self.grid = core.Grid(task.layout.bounds, cell, self.n_robots, self.n_envs)
        self._grid_arrays = self.grid.arrays
        self.move_params = np.array([task.control_period_s, task.platform.wheel_base_m, radius])
        self.sense_params = np.array([radius, BEAM_M, task.comm_range_m])
        self.observe_params = np.array([
            task.ir_noise, task.ir_raw_sd, math.radians(task.light_noise_deg), task.range_noise_m,
            math.radians(task.bearing_noise_deg), task.comm_range_m, float(task.platform.ir_scale == "x80pro"),
            LIGHT_REFERENCE_M,
        ])  # fmt: skip
        self.drive_params = np.array([task.terrain_noise, task.full_speed_mps])
        self.account_params = np.array(
            [task.goal_radius_m, task.control_period_s, float(task.terminate_on_collision), STILL_M]
        )

    def _allocate(self, task) -> None:
        e, rows, k = self.n_envs, self.n_rows, task.n_neighbours
        self.pose = np.zeros((rows, 3))
        self.active = np.zeros(rows, dtype=np.uint8)
        self.circles = np.full((e, task.n_obstacles, 3), [FAR_M, FAR_M, 0.0])
        self.n_circles = np.zeros(e, dtype=np.int64)
        self.goals = np.zeros((e, 2))
        self.cycles = np.zeros(e, dtype=np.int64)
        self.generators: list[np.random.Generator | None] = [None] * e
        self.drift = np.zeros((rows, 2))
        self.powers = np.zeros((rows, 2))
        self.track = np.zeros((rows, N_TRACK))
        self.rewards = np.zeros((rows, len(self.reward_names)))
        self.terminated = np.zeros(rows, dtype=np.uint8)
        self.observations = np.zeros((rows, self.structure["powers"][1]), dtype=np.float32)
        self.normals = np.zeros((rows, 2 + self.sense_draws))  # a step's draws: wheels, then sensors
        self.floor = np.zeros((rows, 4))
        self.beams = np.zeros((rows, 4))
        self.nb_index = np.zeros((rows, k), dtype=np.int64)
        self.nb_range = np.zeros((rows, k))
        self.clearance = np.zeros(rows)
        self._every_row = np.ones(rows, dtype=np.uint8)
        self._one_step = np.ones(e, dtype=np.int64)
        self._wheels = np.zeros((rows, 2))
        self._proposal = np.zeros((rows, 3))
        self._blocked = np.zeros(rows, dtype=np.uint8)
        #: Each environment's generator's C interface (:func:`polyenvs.core.generators.generator_addresses`),
        #: ``None`` until the first step needs it.
        self._addresses: np.ndarray | None = None

    def __getstate__(self) -> dict:
        # The generators' addresses belong to this process's objects: a copy or an unpickled batch finds its own.
        return {**self.__dict__, "_addresses": None}

    def reward_column(self, name: str) -> int:
        """The column of ``rewards`` that holds reward term ``name`` (a task writes its terms there)."""
        return self.reward_names.index(name)

    # --- reset and step ---------------------------------------------------------------------------------------
    def reset(self, envs, generators=None) -> None:
        """New episodes for ``envs`` (environment indices), drawn on ``generators`` (one per environment, which
        the batch keeps) or, if ``None``, on each environment's own; the other environments are left as they are.
        Every episode is drawn before anything changes."""
        envs = [int(e) for e in envs]
        gens = [self.generators[e] for e in envs] if generators is None else list(generators)
        episodes = [self.task.draw_episode(g) for g in gens]
        n = self.n_robots
        sense_normals = np.zeros((self.n_rows, self.sense_draws))
        floor = np.zeros((self.n_rows, 4))
        todo = np.zeros(self.n_rows, dtype=np.uint8)
        for e, g, episode in zip(envs, gens, episodes, strict=True):
            self.generators[e] = g
            if self._addresses is not None:
                self._addresses[e] = compiled_draws.generator_addresses([g])[0]
            rows = slice(e * n, (e + 1) * n)
            self._place(e, episode)
            self.drift[rows] = self.terrain_noise * 0.5 * g.standard_normal((n, 2))
            sense_normals[rows] = g.standard_normal((n, self.sense_draws))
            floor[rows] = g.random((n, 4))
            self.powers[rows] = 0.0
            todo[rows] = 1
        self.cycles[envs] = 0
        self._observe(self.active, todo, sense_normals, floor)
        reset_rows = todo > 0
        self.track[reset_rows] = 0.0
        self.track[reset_rows, DISTANCE] = np.hypot(
            *(self.pose[reset_rows, :2] - np.repeat(self.goals, n, axis=0)[reset_rows]).T
        )
        self.track[reset_rows, MIN_CLEARANCE] = self.clearance[reset_rows]
        self.rewards[reset_rows] = 0.0
        self.terminated[reset_rows] = 0
        env_mask = np.zeros(self.n_envs, dtype=bool)
        env_mask[envs] = True
        self.terms.restart(reset_rows, env_mask)

    def _place(self, e: int, episode) -> None:
        """Environment ``e``'s episode: obstacles, goal and starts; every robot in it."""
        circles = np.asarray(episode.circles, dtype=np.float64).reshape(-1, 3)
        if len(circles) > self.circles.shape[1]:
            raise ValueError(
                f"an episode placed {len(circles)} obstacles, more than n_obstacles {self.circles.shape[1]}"
            )
        rows = slice(e * self.n_robots, (e + 1) * self.n_robots)
        self.circles[e] = (FAR_M, FAR_M, 0.0)
        self.circles[e, : len(circles)] = circles
        self.n_circles[e] = len(circles)
        self.goals[e] = episode.goal
        self.pose[rows] = episode.starts
        self.active[rows] = 1

    def step(self, command: np.ndarray, stepping: np.ndarray | None = None) -> None:
        """One control step of every environment (or of those where the ``(E,)`` mask ``stepping`` is set: the
        others neither draw, move, sense nor score). ``command``: ``(E * N, 2)`` power fractions in [-1, 1]; rows
        of robots out of the episode are ignored. Afterwards ``observations``, ``rewards``, ``terminated`` and the
        metrics are this step's, and robots that terminated have left the episode (``active`` 0)."""
        if stepping is None:
            live, todo, rows = self.active, self._every_row, None
        else:
            todo = np.repeat(stepping, self.n_robots).astype(np.uint8)
            live, rows = self.active & todo, todo > 0
        normals, floor = self.normals, self._draw(self._one_step if stepping is None else stepping)
        wheels = self._wheels
        drive(command, live, (normals, self.drift), self.drive_params, (self.powers, wheels))
        before = self.pose.copy()
        grid = self._grid_arrays
        core.build_grid(self.pose, live, grid)
        core.move(self.pose, live, wheels, self.move_params, (self.walls, self.circles), grid,
                  (self._proposal, self._blocked))  # fmt: skip
        np.add(self.cycles, self._one_step if stepping is None else stepping, out=self.cycles)
        self._observe(live, todo, normals[:, 2:], floor)
        account(self.pose, before, live, (self._blocked, self.clearance), (self.goals, self.n_robots, self.cycles),
                self.account_params, (self.track, self.rewards, self.terminated))  # fmt: skip
        self.terms.score(live, rows, stepping)
        if self.terminated.any():  # rarely: the mask and its assignment cost more than this test
            self.active[self.terminated > 0] = 0

    def _draw(self, stepping: np.ndarray) -> np.ndarray:
        """The step's wheel and sensor normals (into ``normals``) and IR floor uniforms (returned) of the
        environments in ``stepping``, each on its own generator in its own order: one compiled call for the batch
        (:mod:`polyenvs.core.generators`, bit for bit the generators' own methods), or the methods themselves."""
        by_env = self.normals.reshape(self.n_envs, self.n_robots, -1), self.floor.reshape(self.n_envs, self.n_robots, 4)
        if compiled_draws.COMPILED:
            if self._addresses is None:  # the first step, or after unpickling or a deep copy (new generators)
                self._addresses = compiled_draws.generator_addresses(self.generators)
            compiled_draws.normals_then_uniforms(self._addresses, stepping, *by_env)
            return self.floor
        for g, env_normals, env_floor, steps in zip(self.generators, *by_env, stepping.tolist(), strict=True):
            if steps:
                g.standard_normal(out=env_normals)
                g.random(out=env_floor)
        return self.floor

    def _observe(self, live, todo, normals, floor) -> None:
        """Sense the rows in ``todo`` and write their observations (the others are left as they are)."""
        grid = self._grid_arrays
        core.build_grid(self.pose, live, grid)
        core.sense(self.pose, live, todo, self.sense_params, self.angles, (self.walls, self.circles), grid,
                   (self.beams, self.nb_index, self.nb_range, self.clearance))  # fmt: skip
        ir.write_observations((self.pose, live, self.powers), todo, (self.beams, self.nb_index, self.nb_range),
                              self.goals, self.n_robots, (normals, floor), self.observe_params,
                              self.observations)  # fmt: skip
        self.terms.observe(live, todo, normals, self.observations)

    def resense(self, normals: np.ndarray, floor: np.ndarray) -> np.ndarray:
        """Sense every robot again where it stands (after a tool or a test has moved one) with the given sensor
        noise, ``(E * N, sense_draws)`` normals and ``(E * N, 4)`` uniforms (zeros: noiseless); a copy of the new
        observations."""
        self._observe(self.active, self._every_row, np.asarray(normals, np.float64), np.asarray(floor, np.float64))
        return self.observations.copy()

    # --- metrics and info -------------------------------------------------------------------------------------
    def stopped(self) -> np.ndarray:
        """Per robot: still for ``STOPPED_WINDOW_S`` short of the goal (AP-lite's halt)."""
        return (self.track[:, STILL] >= self.stopped_window) & (self.track[:, ARRIVED] == 0)

    def env_metrics(self) -> dict[str, np.ndarray]:
        """Each environment's episode metrics so far, ``(E,)`` arrays by name (``metric_names`` of the task)."""
        track = self.track.reshape(self.n_envs, self.n_robots, N_TRACK)
        metrics = {
            "success_rate": track[:, :, ARRIVED].mean(axis=1),
            "collisions": track[:, :, COLLISIONS].sum(axis=1),
            "time_to_goal_s": track[:, :, TIME_TO_GOAL].mean(axis=1),
            "min_clearance_cm": 100.0 * track[:, :, MIN_CLEARANCE].min(axis=1),
            "stopped": self.stopped().reshape(self.n_envs, self.n_robots).sum(axis=1).astype(np.float64),
        }
        if self.terms.metric_names:
            metrics.update(self.terms.env_metrics())
        return metrics

    def robot_columns(self, fresh: bool = True) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Each robot's info values and episode metrics, ``(E * N, ...)`` arrays by key. Info: true pose, contact
        events, goal distance, the AP-lite diagnostics the paper plots, the reward terms, then the task's keys;
        metrics: ``metric_names`` of the task. The arrays are fresh, or with ``fresh=False`` the one-dimensional
        ones may be views of the state (for a caller that converts them before the next step)."""
        keep = np.copy if fresh else _as_is
        track, stopped = self.track, self.stopped()
        info = {
            "pose": self.pose.copy(),
            "collisions": track[:, COLLISIONS].astype(np.int64),
            "distance_to_goal_m": keep(track[:, DISTANCE]),
            "nearest_obstacle_cm": np.minimum(100.0 * self.beams, ir.IR_MAX_CM),
            "motor_powers": 100.0 * self.powers,
            "turning_angle_deg": np.degrees(track[:, TURN]),
            "stopped": stopped,
        }
        for key, column in zip(self._reward_keys, keep(self.rewards.T), strict=True):
            info[key] = column
        if self.terms.info_names:
            info.update(self.terms.robot_info())
        metrics = {
            "success_rate": keep(track[:, ARRIVED]),
            "collisions": keep(track[:, COLLISIONS]),
            "time_to_goal_s": keep(track[:, TIME_TO_GOAL]),
            "min_clearance_cm": 100.0 * track[:, MIN_CLEARANCE],
            "stopped": stopped.astype(np.float64),
        }
        if self.terms.metric_names:
            metrics.update(self.terms.robot_metrics())
        return info, metrics

    def robot_row(self, row: int) -> tuple[dict[str, Any], dict[str, float]] | None:
        """:meth:`robot_columns` for robot ``row`` alone, the same values as their rows give (Python numbers, fresh
        arrays for the vector keys), without an array operation per key: what a swarm of one reports every step.
        ``None`` when the task adds info or metrics of its own (they come as columns only)."""
        if self.terms.info_names or self.terms.metric_names:
            return None
        track = self.track[row].tolist()
        stopped = track[STILL] >= self.stopped_window and track[ARRIVED] == 0
        info = {
            "pose": self.pose[row].copy(),
            "collisions": int(track[COLLISIONS]),
            "distance_to_goal_m": track[DISTANCE],
            "nearest_obstacle_cm": np.minimum(100.0 * self.beams[row], ir.IR_MAX_CM),
            "motor_powers": 100.0 * self.powers[row],
            "turning_angle_deg": math.degrees(track[TURN]),
            "stopped": stopped,
            **dict(zip(self._reward_keys, self.rewards[row].tolist(), strict=True)),
        }
        metrics = {
            "success_rate": track[ARRIVED],
            "collisions": track[COLLISIONS],
            "time_to_goal_s": track[TIME_TO_GOAL],
            "min_clearance_cm": 100.0 * track[MIN_CLEARANCE],
            "stopped": float(stopped),
        }
        return info, metrics


def _as_is(array: np.ndarray) -> np.ndarray:
    return array
