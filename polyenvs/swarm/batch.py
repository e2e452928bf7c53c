"""The swarm's one core: E environments of N robots, stepped, reset, scored and measured together.

:class:`SwarmBatch` is what every swarm surface runs on, at batch size 1 (the PettingZoo environment of
:mod:`polyenvs.swarm.env`) or E (the vector envs of :mod:`polyenvs.swarm.batched` and :mod:`polyenvs.swarm.vector`),
so the step, the reset, the rewards and the metrics exist once. A step is one noise draw per environment and one
compiled call for all E x N robots (:func:`step_kernel`: :mod:`polyenvs.swarm.core`'s grid, move and sense;
:func:`polyenvs.swarm.sensors.write_observations`; :func:`account`), what the task adds included.

Rows: robot ``r`` of environment ``e`` is row ``e * N + r``. Every environment has its own generator and draws in
one fixed order, at a reset the episode (the task's ``sample_episode``), the wheels' drift and the first readings'
noise, then at each step the wheels' and sensors' normals and the IR floor; so environment ``e`` reset with
generator ``g`` is, bit for bit, a batch of one reset with ``g``, whatever the other environments do.

What a task adds to the family (the formation's leader, its reward term and metric) it declares by name in a
:class:`TaskTerms` subclass, which the batch builds with itself and calls at each reset and step, in Python or in
the task's compiled step (:attr:`TaskTerms.compiled_step`: :func:`step_kernel`, then the task's own terms, in the
same one call): the core knows no task.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from polyenvs.core import generators as compiled_draws
from polyenvs.core.jit import KernelArgs, compiled_for, njit
from polyenvs.core.rows import read_only
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
    "step_kernel",
    "write_info",
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


#: Columns of the per-robot info table ``SwarmBatch.info_table`` (:func:`write_info`): floats a surface reads with
#: one ``tolist``; then the family's reward terms, in ``REWARD_NAMES`` order. ``INFO_REWARD`` is a step's reward:
#: the terms summed in column order, the family's by :func:`write_info`, a task's added by its compiled step (as
#: numpy's ``rewards.sum(axis=1)`` sums them).
INFO_DISTANCE, INFO_TURN_DEG, INFO_REWARD, INFO_TERMS = range(4)


@njit(cache=True)
def write_info(track, rewards, sensed, stopped_window, out):
    """Every robot's per-step info values from the state, in place: the info table (goal distance, turning angle
    in degrees, the family's reward (its terms' sum, in column order) and the terms), contact events, whether it
    is stopped short of the goal, and the AP-lite diagnostics the paper plots (distance per beam to the nearest
    obstacle, clipped at the IR's reach, and the motor powers, in percent).

    Args:
        sensed: ``(beams, powers)``.
        out: ``(table, collisions, stopped, nearest_cm, motor_powers)``, written.
    """
    beams, powers = sensed
    table, collisions, stopped, nearest_cm, motor_powers = out
    for i in range(track.shape[0]):
        table[i, INFO_DISTANCE] = track[i, DISTANCE]
        table[i, INFO_TURN_DEG] = track[i, TURN] * (180.0 / math.pi)
        total = rewards[i, 0]
        table[i, INFO_TERMS] = rewards[i, 0]
        for t in range(1, len(REWARD_NAMES)):
            total += rewards[i, t]
            table[i, INFO_TERMS + t] = rewards[i, t]
        table[i, INFO_REWARD] = total
        collisions[i] = int(track[i, COLLISIONS])
        stopped[i] = track[i, STILL] >= stopped_window and track[i, ARRIVED] == 0.0
        for s in range(beams.shape[1]):
            nearest_cm[i, s] = min(100.0 * beams[i, s], ir.IR_MAX_CM)
        motor_powers[i, 0] = 100.0 * powers[i, 0]
        motor_powers[i, 1] = 100.0 * powers[i, 1]


@njit(cache=True)
def _draw_compiled(draws, stepping):
    """The step's normals and IR floor uniforms of the environments in ``stepping``, on each one's generator
    (:func:`polyenvs.core.generators.normals_then_uniforms`); ``draws = (addresses, normals, floor, ...)``, the
    second and third ``(E, N, ...)`` views."""
    addresses, normals, floor = draws[0], draws[1], draws[2]
    if addresses.shape[0] > 0:
        compiled_draws.normals_then_uniforms(addresses, stepping, normals, floor)


@njit(cache=True)
def step_kernel(kernel):
    """One control step of the environments marked in ``stepping`` (the others neither draw, move, sense nor
    score), in one compiled call: the draws, :func:`drive`, the grid, :func:`polyenvs.swarm.core.move`, the
    sensing and observations, :func:`account`, :func:`write_info`; robots that terminated leave the episode.

    ``kernel`` (:class:`polyenvs.core.jit.KernelArgs`, built by :meth:`SwarmBatch._pack`): ``sim`` the state and
    scratch, ``out`` what a step writes, ``task`` the parameters, then the task's own arrays
    (:meth:`TaskTerms.kernel_arrays`). ``live`` and ``todo`` are left holding the robots that took the step and the
    rows it sensed, for a task's compiled step (:attr:`TaskTerms.compiled_step`), which calls this one first.
    """
    (robots, scene, grid, draws, scratch, sensed) = kernel.sim
    command, stepping, todo, live, before, wheels, proposal, blocked = scratch
    pose, active, drift, powers, goals, cycles = robots
    observations, track, rewards, terminated, info = kernel.out
    drive_params, move_params, sense_params, angles, observe_params, account_params, shape, _ = kernel.task
    per, stopped_window, draw = shape[0], shape[1], shape[2]
    for i in range(pose.shape[0]):
        todo[i] = stepping[i // per]
        live[i] = active[i] & todo[i]
    if draw:
        _draw_compiled(draws, stepping)
    normals, floor = draws[3], draws[4]
    drive(command, live, (normals, drift), drive_params, (powers, wheels))
    before[:] = pose
    core.build_grid(pose, live, grid)
    core.move(pose, live, wheels, move_params, scene, grid, (proposal, blocked))
    for e in range(cycles.shape[0]):
        cycles[e] += stepping[e]
    core.build_grid(pose, live, grid)
    core.sense(pose, live, todo, sense_params, angles, scene, grid, sensed)
    ir.write_observations((pose, live, powers), todo, (sensed[0], sensed[1], sensed[2]), goals, per,
                          (normals[:, 2:], floor), observe_params, observations)  # fmt: skip
    account(pose, before, live, (blocked, sensed[3]), (goals, per, cycles), account_params,
            (track, rewards, terminated))  # fmt: skip
    write_info(track, rewards, (sensed[0], powers), stopped_window, info)
    for i in range(pose.shape[0]):
        if terminated[i]:
            active[i] = 0


class TaskTerms:
    """What a task adds to the family, declared by name, and computed for a whole batch. The family's own tasks
    add nothing (this class); the formation adds its leader, a reward term and a metric
    (:class:`polyenvs.swarm.formation_v0.FormationTerms`). A task names its subclass in ``terms_class``.

    Class attributes:
        compiled_step: the batch's step, one compiled function of a :class:`~polyenvs.core.jit.KernelArgs`:
            :func:`step_kernel`, whereupon the batch calls :meth:`observe` and :meth:`score` in Python, or the
            task's own, which calls it, then writes the task's observation parts and reward terms (adding them to
            the info table's reward) from the arrays of :meth:`kernel_arrays` (the last element of
            ``kernel.task``), and replaces those two calls.
        observation_parts: name -> the lower bounds of its columns (every upper bound is 1), placed in this order
            between ``neighbours`` and ``powers``.
        reward_names: reward terms after the family's (each in ``info["reward_<name>"]``, written by :meth:`score`
            or ``compiled_step`` into their :meth:`SwarmBatch.reward_column`).
        metric_names: episode metrics after the family's (:meth:`env_metrics`, :meth:`robot_metrics`).
        info_names: per-robot info keys after the family's (:meth:`robot_info`; both in
            :meth:`SwarmBatch.robot_columns`).

    Masks below are ``None`` (every row, every environment) or boolean arrays over rows and environments.
    """

    compiled_step = staticmethod(step_kernel)
    observation_parts: dict[str, tuple[float, ...]] = {}
    reward_names: tuple[str, ...] = ()
    metric_names: tuple[str, ...] = ()
    info_names: tuple[str, ...] = ()

    def __init__(self, task, batch: SwarmBatch):
        self.batch = batch

    def kernel_arrays(self) -> tuple:
        """What the task's ``compiled_step`` reads and writes besides the batch's arrays (none here)."""
        return ()

    def observe(self, live: np.ndarray, todo: np.ndarray, normals: np.ndarray, out: np.ndarray) -> None:
        """Write the task's observation parts of the rows in ``todo`` into ``out`` (the family has zeroed them);
        ``normals`` are the sensors' draws, whose last ``TASK_NORMALS`` columns are the task's; ``live`` marks the
        robots in the episode. After a step only without a ``compiled_step`` of the task's own."""

    def score(self, live: np.ndarray, rows, envs) -> None:
        """After a step of the ``rows`` of ``envs`` (``live``: the robots that took it), without a
        ``compiled_step`` of the task's own: the task's reward terms and running sums."""

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
        # Whether the task observes or scores in Python after the compiled step (a task outside the package).
        terms_class = type(self.terms)
        self._task_steps = terms_class.compiled_step is step_kernel and (
            terms_class.observe is not TaskTerms.observe or terms_class.score is not TaskTerms.score
        )

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
        #: The kernel's inputs and scratch: the step's power fractions, which environments step, the rows it
        #: senses and the robots that take it, the poses before it.
        self.command = np.zeros((rows, 2))
        self._stepping = np.ones(e, dtype=np.int64)
        self._masked = False
        self._todo = np.ones(rows, dtype=np.uint8)
        self.live = np.zeros(rows, dtype=np.uint8)
        self._before = np.zeros((rows, 3))
        self._wheels = np.zeros((rows, 2))
        self._proposal = np.zeros((rows, 3))
        self._blocked = np.zeros(rows, dtype=np.uint8)
        #: Per-robot info values (:func:`write_info`): a float table (``INFO_*`` columns), contact events, stopped,
        #: nearest obstacle per beam (cm) and motor powers (%).
        self.info_table = np.zeros((rows, INFO_TERMS + len(REWARD_NAMES)))
        self.info_collisions = np.zeros(rows, dtype=np.int64)
        self.info_stopped = np.zeros(rows, dtype=np.bool_)
        self.nearest_cm = np.zeros((rows, 4))
        self.motor_powers = np.zeros((rows, 2))
        #: Each environment's generator's C interface (:func:`polyenvs.core.generators.generator_addresses`),
        #: ``None`` until the first step needs it.
        self._addresses: np.ndarray | None = None
        #: The compiled step's packed arguments and machine code (:meth:`_pack`), built at the first step.
        self._step_call: tuple[Any, KernelArgs] | None = None
        self._views: dict[str, np.ndarray] | None = None

    def __getstate__(self) -> dict:
        # The generators' addresses belong to this process's objects, and the packed arguments are compiled-code
        # memory: a copy or an unpickled batch builds its own.
        return {**self.__dict__, "_addresses": None, "_step_call": None, "_views": None}

    def _pack(self) -> tuple[Any, KernelArgs]:
        """The compiled step's arguments (:func:`step_kernel`) as one :class:`~polyenvs.core.jit.KernelArgs`, and its
        machine code for them (the generators' addresses with them)."""
        draw = compiled_draws.COMPILED
        self._addresses = compiled_draws.generator_addresses(self.generators if draw else [])
        by_env = self.normals.reshape(self.n_envs, self.n_robots, -1), self.floor.reshape(self.n_envs, self.n_robots, 4)
        sim = (
            (self.pose, self.active, self.drift, self.powers, self.goals, self.cycles),
            (self.walls, self.circles),
            self._grid_arrays,
            (self._addresses, *by_env, self.normals, self.floor),
            (self.command, self._stepping, self._todo, self.live, self._before, self._wheels, self._proposal,
             self._blocked),
            (self.beams, self.nb_index, self.nb_range, self.clearance),
        )  # fmt: skip
        out = (self.observations, self.track, self.rewards, self.terminated, self._info_out)
        shape = np.array([self.n_robots, self.stopped_window, int(draw)], dtype=np.int64)
        task = (self.drive_params, self.move_params, self.sense_params, self.angles, self.observe_params,
                self.account_params, shape, self.terms.kernel_arrays())  # fmt: skip
        kernel = KernelArgs(sim, out, task)
        return compiled_for(self.terms.compiled_step, kernel), kernel

    @property
    def _info_out(self) -> tuple:
        return self.info_table, self.info_collisions, self.info_stopped, self.nearest_cm, self.motor_powers

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
            if self._addresses is not None and compiled_draws.COMPILED:  # without numba: no addresses
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
        self._write_info()

    def _write_info(self) -> None:
        """The info table from the state (after a reset or a re-sensing; a step writes it in its kernel)."""
        write_info(self.track, self.rewards, (self.beams, self.powers), self.stopped_window, self._info_out)

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

    def step(self, command: np.ndarray | None = None, stepping: np.ndarray | None = None) -> None:
        """One control step of every environment (or of those where the ``(E,)`` mask ``stepping`` is set: the
        others neither draw, move, sense nor score), in one compiled call (:attr:`TaskTerms.compiled_step`), what
        the task adds included. ``command``: ``(E * N, 2)`` power fractions in [-1, 1] (``None``: what the caller
        has written into :attr:`command`); rows of robots out of the episode are ignored. Afterwards
        ``observations``, ``rewards``, ``terminated``, the info table and the metrics are this step's, and robots
        that terminated have left the episode (``active`` 0)."""
        if command is not None:
            self.command[:] = command
        if stepping is not None or self._masked:  # the mask of every environment stays until a masked step
            self._stepping[:] = 1 if stepping is None else stepping
            self._masked = stepping is not None
        if self._step_call is None:  # the first step, or after unpickling or a deep copy (new generators)
            self._step_call = self._pack()
        if not compiled_draws.COMPILED:
            self._draw_each(self._stepping)
        step, kernel = self._step_call
        step(kernel)
        if self._task_steps:
            terms = self.terms
            terms.observe(self.live, self._todo, self.normals[:, 2:], self.observations)
            terms.score(self.live, None if stepping is None else self._todo > 0, stepping)

    def step_rewards(self) -> np.ndarray:
        """Each robot's reward of the last step, ``(E * N,)``: its terms summed in column order. The info table's
        (to which a task's compiled step adds its terms), or, where the task scores in Python, the sum of
        ``rewards``' columns (numpy adds a row's few columns one after the other, as the table does)."""
        if self._task_steps and self.terms.reward_names:
            return self.rewards.sum(axis=1)
        return self.info_table[:, INFO_REWARD]

    def _draw_each(self, stepping: np.ndarray) -> None:
        """The step's draws through the generators' own methods (where nothing is compiled), as
        :func:`_draw_compiled` makes them."""
        by_env = self.normals.reshape(self.n_envs, self.n_robots, -1), self.floor.reshape(self.n_envs, self.n_robots, 4)
        for g, env_normals, env_floor, steps in zip(self.generators, *by_env, stepping.tolist(), strict=True):
            if steps:
                g.standard_normal(out=env_normals)
                g.random(out=env_floor)

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
        self._write_info()
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

    def robot_views(self) -> dict[str, np.ndarray]:
        """The per-robot info arrays a step hands over without a copy, ``(E * N, ...)`` read-only views of the
        state made once: true ``pose``, ``nearest_obstacle_cm`` and ``motor_powers``. Valid until the next step or
        reset (copy them to keep them)."""
        if self._views is None:
            self._views = {
                "pose": read_only(self.pose),
                "nearest_obstacle_cm": read_only(self.nearest_cm),
                "motor_powers": read_only(self.motor_powers),
            }
        return self._views

    def robot_columns(self) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Each robot's info values and episode metrics, ``(E * N, ...)`` arrays by key. Info: true pose, contact
        events, goal distance, the AP-lite diagnostics the paper plots, the reward terms, then the task's keys
        (the arrays of :meth:`robot_views` as they are, the others fresh); metrics: ``metric_names`` of the task
        (fresh)."""
        views, table = self.robot_views(), self.info_table
        info = {
            "pose": views["pose"],
            "collisions": self.info_collisions.copy(),
            "distance_to_goal_m": table[:, INFO_DISTANCE].copy(),
            "nearest_obstacle_cm": views["nearest_obstacle_cm"],
            "motor_powers": views["motor_powers"],
            "turning_angle_deg": table[:, INFO_TURN_DEG].copy(),
            "stopped": self.info_stopped.copy(),
        }
        for key, column in zip(self._reward_keys, self.rewards.T.copy(), strict=True):
            info[key] = column
        if self.terms.info_names:
            info.update(self.terms.robot_info())
        return info, self.robot_metrics()

    def robot_metrics(self) -> dict[str, np.ndarray]:
        """Each robot's episode metrics so far, ``(E * N,)`` fresh arrays by name (``metric_names`` of the task)."""
        track = self.track
        metrics = {
            "success_rate": track[:, ARRIVED].copy(),
            "collisions": track[:, COLLISIONS].copy(),
            "time_to_goal_s": track[:, TIME_TO_GOAL].copy(),
            "min_clearance_cm": 100.0 * track[:, MIN_CLEARANCE],
            "stopped": self.stopped().astype(np.float64),
        }
        if self.terms.metric_names:
            metrics.update(self.terms.robot_metrics())
        return metrics

    def robot_metrics_row(self, row: int) -> dict[str, float]:
        """Robot ``row``'s episode metrics so far, as Python floats (the values of its row of
        :meth:`robot_metrics`)."""
        return {name: float(value[row]) for name, value in self.robot_metrics().items()}
