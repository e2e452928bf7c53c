"""The PettingZoo surface shared by the swarm tasks: spaces, seeding, sensing, rewards, info and metrics.

A task (``corridor_v0``, ``obstacle_field_v0``, ``formation_v0``) subclasses :class:`SwarmEnv` and provides
``_fixed_layout`` (walls and view bounds, once per instance) and ``_sample_episode`` (obstacles, starts and goal,
drawn on the episode's generator at every reset). Everything per step works on arrays over robots: one noise draw,
two compiled calls (:func:`polyenvs.swarm.core.move`, :func:`polyenvs.swarm.core.sense`), a few numpy operations
for observations and rewards; only the PettingZoo dictionaries are built per agent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils import OrderEnforcingWrapper
from pettingzoo.utils.conversions import parallel_to_aec_wrapper

from polyenvs.core.jit import njit
from polyenvs.core.validation import (
    check_action,
    check_bool,
    check_in_range,
    check_int,
    check_options,
    real_array,
    show,
)
from polyenvs.swarm import core
from polyenvs.swarm import sensors as ir
from polyenvs.swarm.platforms import SENSOR_ANGLES_DEG, get_platform

__all__ = [
    "DEFAULT_COMM_RANGE_M",
    "Episode",
    "Layout",
    "PARAMETER_RANGES",
    "PETTINGZOO_PROBE_OPTION",
    "SwarmAECEnv",
    "SwarmEnv",
    "SwarmOrderEnforcingWrapper",
    "check_swarm_options",
    "module_constructors",
    "observation_structure",
    "structure_for",
]

#: Physical parameters: (low, high) plausible range. Outside it a parameter is refused at construction.
PARAMETER_RANGES = {
    "control_period_s": (0.02, 1.0),
    "full_speed_mps": (0.05, 1.0),
    "terrain_noise": (0.0, 0.3),
    "ir_noise": (0.0, 0.2),
    "ir_raw_sd": (0.0, 20.0),
    "comm_range_m": (0.5, 10.0),
    "range_noise_m": (0.0, 0.2),
    "bearing_noise_deg": (0.0, 20.0),
    "light_noise_deg": (0.0, 20.0),
    "goal_radius_m": (0.1, 3.0),
    "sensor_angle_deg": (-90.0, 90.0),
}
#: Trilateration reach when not given (m).
DEFAULT_COMM_RANGE_M = 3.0
#: GP2D12 reach (Sharp data sheet): beyond it the reading is the noise floor.
BEAM_M = ir.IR_MAX_CM / 100.0
#: Intensity of the goal light is 1 / (1 + (d / LIGHT_REFERENCE_M)^2) (inverse square, *ours*).
LIGHT_REFERENCE_M = 1.0
#: A robot that has moved less than this per step for STOPPED_WINDOW_S counts as stopped.
STILL_M = 1e-3
STOPPED_WINDOW_S = 1.0
#: Reward weights (*ours*): per metre of progress, per step in contact, on arrival, per unit formation error.
PROGRESS_PER_M = 10.0
COLLISION_PENALTY = 1.0
ARRIVAL_BONUS = 10.0
FORMATION_PENALTY = 0.1
#: The wheels' speed factor under terrain noise is clipped to [0, MAX_SPEED_FACTOR].
MAX_SPEED_FACTOR = 1.5


#: Columns of the per-robot bookkeeping array ``SwarmEnv._track``.
DISTANCE, TURN, STILL, COLLISIONS, WAS_BLOCKED, ARRIVED, TIME_TO_GOAL, MIN_CLEARANCE = range(8)
N_TRACK = 8


@njit(cache=True)
def account(pose, before, active, blocked, clearance, goals, per, cycles, params, track, rewards, terminated):
    """Score one step for every active robot: the three reward terms, arrival and termination, and the running
    episode metrics in ``track`` (turn, still steps, contact events, time, smallest clearance).

    Args:
        before: ``(N, 3)`` poses before the step.
        goals: ``(E, 2)`` each environment's goal; ``per``: robots per environment; ``cycles``: ``(E,)`` steps
            so far in each environment's episode.
        params: ``[goal_radius_m, dt_s, terminate_on_collision, still_m]``.
    """
    goal_radius, dt, stop_on_contact, still_m = params[0], params[1], params[2] > 0.5, params[3]
    for i in range(pose.shape[0]):
        terminated[i] = 0
        rewards[i, 0] = 0.0
        rewards[i, 1] = 0.0
        rewards[i, 2] = 0.0
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
        rewards[i, 0] = PROGRESS_PER_M * (track[i, DISTANCE] - distance)
        rewards[i, 1] = -COLLISION_PENALTY if contact else 0.0
        rewards[i, 2] = ARRIVAL_BONUS if arrived else 0.0
        track[i, DISTANCE] = distance
        if arrived:
            track[i, ARRIVED] = 1.0
        track[i, TIME_TO_GOAL] = cycles[e] * dt
        track[i, MIN_CLEARANCE] = min(track[i, MIN_CLEARANCE], clearance[i])
        terminated[i] = 1 if arrived or (contact and stop_on_contact) else 0


#: PettingZoo's ``api_test`` and ``parallel_api_test`` check that reset takes options by calling
#: ``reset(seed=0, options={"options": 1})``: that one key is ignored, so the swarm passes PettingZoo's own tests.
PETTINGZOO_PROBE_OPTION = "options"


def check_swarm_options(options) -> dict:
    """A PettingZoo swarm's reset options: ``None`` or a dict with no keys but PettingZoo's API-test probe
    (:data:`PETTINGZOO_PROBE_OPTION`, ignored); else ``ValueError`` ("options must be a dict or None", "unknown
    reset option(s) [...]"), before anything changes."""
    if isinstance(options, dict) and PETTINGZOO_PROBE_OPTION in options:
        options = {k: v for k, v in options.items() if k != PETTINGZOO_PROBE_OPTION}
    return check_options(options, ())


@dataclass
class Layout:
    """What stays fixed for the life of an instance: the wall segments ``(W, 4)`` and the frame's bounds."""

    walls: np.ndarray
    bounds: tuple[float, float, float, float]


@dataclass
class Episode:
    """What a reset draws: obstacles ``(C, 3)``, start poses ``(N, 3)`` and the goal light ``(2,)``."""

    circles: np.ndarray
    starts: np.ndarray
    goal: np.ndarray


class SwarmEnv(ParallelEnv):
    """Base class of the swarm tasks (see the task modules for the full documentation)."""

    metadata = {"render_modes": ["rgb_array", "human"], "name": "swarm", "is_parallelizable": True, "render_fps": 10}
    reward_names: tuple[str, ...] = ("progress", "collision", "arrival")
    metric_names = ("success_rate", "collisions", "time_to_goal_s", "min_clearance_cm", "stopped")
    #: Formation tasks add the leader's trilateration and a formation error (set by the formation task).
    formation = False
    default_platform = "maxelbot"

    def __init__(
        self,
        *,
        n_robots: int = 1,
        platform: str | None = None,
        max_cycles: int = 500,
        control_period_s: float = 0.1,
        full_speed_mps: float = 0.5,
        terrain_noise: float = 0.05,
        ir_noise: float = 0.03,
        ir_raw_sd: float = 2.0,
        comm_range_m: float = DEFAULT_COMM_RANGE_M,
        n_neighbours: int = 6,
        range_noise_m: float = 0.02,
        bearing_noise_deg: float = 2.0,
        light_noise_deg: float = 2.0,
        goal_radius_m: float = 0.4,
        sensor_angles_deg=SENSOR_ANGLES_DEG,
        terminate_on_collision: bool = False,
        flat_info: bool = False,
        render_mode: str | None = None,
    ):
        self.n_robots = check_int("n_robots", n_robots, 1, 1024)
        self.platform = get_platform(self.default_platform if platform is None else platform)
        self.max_cycles = check_int("max_cycles", max_cycles, 1, 1_000_000)
        given = dict(
            control_period_s=control_period_s, full_speed_mps=full_speed_mps, terrain_noise=terrain_noise,
            ir_noise=ir_noise, ir_raw_sd=ir_raw_sd, comm_range_m=comm_range_m, range_noise_m=range_noise_m,
            bearing_noise_deg=bearing_noise_deg, light_noise_deg=light_noise_deg, goal_radius_m=goal_radius_m,
        )  # fmt: skip
        p = {name: check_in_range(name, value, *PARAMETER_RANGES[name]) for name, value in given.items()}
        self.__dict__.update(p)
        self.n_neighbours = check_int("n_neighbours", n_neighbours, 1, 32)
        try:
            angles = [
                check_in_range("sensor_angles_deg", a, *PARAMETER_RANGES["sensor_angle_deg"]) for a in sensor_angles_deg
            ]
        except TypeError:
            raise ValueError(f"sensor_angles_deg must be four angles, got {show(sensor_angles_deg)}") from None
        if len(angles) != 4 or sorted(angles) != angles:
            raise ValueError(
                f"sensor_angles_deg must be four increasing angles (S0 right-most), got {show(sensor_angles_deg)}"
            )
        self.sensor_angles_deg = tuple(angles)
        self.terminate_on_collision = check_bool("terminate_on_collision", terminate_on_collision)
        self.flat_info = check_bool("flat_info", flat_info)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        # One frame per control step.
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.control_period_s))}
        radius = self.platform.radius_m
        self.max_step_m = self.full_speed_mps * MAX_SPEED_FACTOR * self.control_period_s
        if self.max_step_m >= radius:
            raise ValueError(
                f"control_period_s * full_speed_mps lets a robot move {self.max_step_m:.3f} m in one step "
                f"(at {MAX_SPEED_FACTOR:g}x speed), not less than its radius {radius:g} m: it could pass a wall"
            )
        self._task_init()
        self.layout = self._fixed_layout()

        n, k = self.n_robots, self.n_neighbours
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agents: list[str] = []
        self.agent_name_mapping = {a: i for i, a in enumerate(self.possible_agents)}
        self.observation_structure = observation_structure(k, self.formation)
        size = self.observation_structure["powers"][1]
        low = [0.0] * 4 + [-1.0, 0.0] + [0.0, -1.0, 0.0] * k + ([0.0, -1.0, 0.0, 0.0] if self.formation else [])
        low += [-1.0, -1.0]
        obs_space = spaces.Box(np.array(low, np.float32), np.ones(size, np.float32), dtype=np.float32)
        act_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        # One space object per agent, built once (action-space seeding then acts on what step() checks).
        self.observation_spaces = {
            a: obs_space if i == 0 else _copy_box(obs_space) for i, a in enumerate(self.possible_agents)
        }
        self.action_spaces = {
            a: act_space if i == 0 else _copy_box(act_space) for i, a in enumerate(self.possible_agents)
        }
        xmin, ymin, xmax, ymax = self.layout.bounds
        self.state_space = spaces.Box(
            np.tile(np.array([xmin, ymin, -1.0, -1.0, 0.0], np.float32), n),
            np.tile(np.array([xmax, ymax, 1.0, 1.0, 1.0], np.float32), n),
            dtype=np.float32,
        )

        self._angles = np.radians(np.array(self.sensor_angles_deg))
        self._walls = np.ascontiguousarray(self.layout.walls, dtype=np.float64)[None]
        self._cell_m = core.cell_size(radius, BEAM_M, self.comm_range_m, self.max_step_m)
        self._grid = core.Grid(self.layout.bounds, self._cell_m, n)
        self._move_params = np.array([self.control_period_s, self.platform.wheel_base_m, radius])
        self._sense_params = np.array([radius, BEAM_M, self.comm_range_m])
        self._observe_params = np.array([
            self.ir_noise, self.ir_raw_sd, math.radians(self.light_noise_deg), self.range_noise_m,
            math.radians(self.bearing_noise_deg), self.comm_range_m, float(self.platform.ir_scale == "x80pro"),
            LIGHT_REFERENCE_M,
        ])  # fmt: skip
        self._leader_at = self.observation_structure["leader"][0] if self.formation else -1
        self._track = np.zeros((n, N_TRACK))
        self._account_params = np.array(
            [self.goal_radius_m, self.control_period_s, float(self.terminate_on_collision), STILL_M]
        )
        self._obs_size = size
        self._sense_draws = 11 + 2 * k
        self.pose = np.zeros((n, 3))
        self.active = np.zeros(n, dtype=np.uint8)
        self._all_rows = np.ones(n, dtype=np.uint8)
        self._proposal = np.zeros((n, 3))
        self._blocked = np.zeros(n, dtype=np.uint8)
        self._beams = np.zeros((n, 4))
        self._nb_index = np.zeros((n, k), dtype=np.int64)
        self._nb_range = np.zeros((n, k))
        self._clearance = np.zeros(n)
        self._wheels = np.zeros((n, 2))
        self._rng: np.random.Generator | None = None
        self._np_random_seed = None
        self._renderer = None
        self.circles = np.zeros((0, 3))
        self.goal = np.zeros(2)
        self.num_cycles = 0
        self._started = False  # step() and render() need a first reset()

    # --- task interface ---------------------------------------------------------------------------------------
    def _task_init(self) -> None:
        """Check the task's own parameters (before the layout is built)."""

    def _fixed_layout(self) -> Layout:
        raise NotImplementedError

    def _sample_episode(self, rng: np.random.Generator) -> Episode:
        raise NotImplementedError

    def _formation_error(self) -> tuple[np.ndarray, float]:
        """Per-robot and swarm formation error (formation tasks only)."""
        return np.zeros(self.n_robots), 0.0

    # --- PettingZoo API ---------------------------------------------------------------------------------------
    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        if self._rng is None:
            self._rng, self._np_random_seed = seeding.np_random()
        return self._rng

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode. The swarm takes no reset options: ``options`` must be ``None`` or ``{}`` (anything else
        raises ``ValueError`` and changes nothing), save the key PettingZoo's own API tests probe with, ignored
        (see :func:`check_swarm_options`)."""
        check_swarm_options(options)
        if seed is not None:
            rng, used = seeding.np_random(seed)
        else:
            rng, used = self.np_random, self._np_random_seed
        episode = self._sample_episode(rng)
        self._rng, self._np_random_seed = rng, used
        n = self.n_robots
        self.circles = np.ascontiguousarray(episode.circles, dtype=np.float64).reshape(-1, 3)
        self._circles = self.circles[None]
        self.goal = np.asarray(episode.goal, dtype=np.float64)
        self.pose[:] = episode.starts
        self.active[:] = 1
        self.agents = self.possible_agents[:]
        self.num_cycles = 0
        # Per-episode wheel drift (terrain: slopes and grass pull one wheel), then per-step noise.
        self._drift = self.terrain_noise * 0.5 * rng.standard_normal((n, 2))
        self._powers = np.zeros((n, 2))
        self._blocked[:] = 0
        self._formation_sum = np.zeros(n)
        self._formation_total, self._formation_steps = 0.0, 0  # a running mean: memory stays bounded
        self._rewards = np.zeros((n, len(self.reward_names)))
        obs = self._sense(rng.standard_normal((n, self._sense_draws)), rng.random((n, 4)))
        self._track[:] = 0.0
        self._track[:, DISTANCE] = np.hypot(*(self.pose[:, :2] - self.goal).T)
        self._track[:, MIN_CLEARANCE] = self._clearance
        self._update_metrics()
        infos = self._infos(range(n))
        self._started = True
        if self.render_mode == "human":
            self.render()
        return {a: obs[i] for i, a in enumerate(self.agents)}, infos

    def step(self, actions):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        n = self.n_robots
        command = self._command(actions)
        if not self.agents:
            # Every robot has left: nothing moves (SuperSuit's black_death wrapper steps once more with no actions).
            return {}, {}, {}, {}, {}
        rng = self._rng
        # One draw per step, in a fixed order (wheels, then sensors; then the IR floor), so a batched vector env
        # drawing from each sub-environment's generator reproduces this environment bit for bit.
        normals = rng.standard_normal((n, 2 + self._sense_draws))
        floor = rng.random((n, 4))
        noise = 1.0 + self.terrain_noise * normals[:, :2] + self._drift
        self._wheels[:] = command * self.full_speed_mps * np.clip(noise, 0.0, MAX_SPEED_FACTOR)
        before = self.pose.copy()
        g = self._grid
        core.build_grid(self.pose, self.active, *g.arrays)
        core.move(self.pose, self.active, self._wheels, self._move_params, self._walls, self._circles, *g.arrays,
                  self._proposal, self._blocked)  # fmt: skip
        self.num_cycles += 1
        self._powers = command * self.active[:, None]
        obs = self._sense(normals[:, 2:], floor)
        terminated = np.zeros(n, dtype=np.uint8)
        account(self.pose, before, self.active, self._blocked, self._clearance, self.goal[None], self.n_robots,
                np.array([self.num_cycles]), self._account_params, self._track, self._rewards, terminated)  # fmt: skip
        self._update_metrics()
        terminated = terminated.astype(bool)
        truncate = self.num_cycles >= self.max_cycles
        agents = self.agents
        index = [self.agent_name_mapping[a] for a in agents]
        reward = self._rewards.sum(axis=1).tolist()
        term = terminated.tolist()
        observations = {a: obs[i] for a, i in zip(agents, index, strict=True)}
        rewards = {a: reward[i] for a, i in zip(agents, index, strict=True)}
        terminations = {a: term[i] for a, i in zip(agents, index, strict=True)}
        truncations = {a: truncate and not term[i] for a, i in zip(agents, index, strict=True)}
        infos = self._infos(index)
        self.active[terminated] = 0
        self.agents = [] if truncate else [a for a, i in zip(agents, index, strict=True) if not term[i]]
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _command(self, actions) -> np.ndarray:
        """The ``(N, 2)`` power fractions of a step's actions, all checked before anything changes. Actions must
        be real numbers: complex, bool, string and object input is refused, not cast. The common case (arrays of
        a real dtype) is one array test; anything else, or a batch that fails it, is checked agent by agent, which
        names the culprit."""
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict of agent -> action, got {show(actions)}")
        rows = [self.agent_name_mapping.get(agent) for agent in actions]
        if any(i is None or not self.active[i] for i in rows):
            bad = next(a for a, i in zip(actions, rows, strict=True) if i is None or not self.active[i])
            raise ValueError(f"action for {show(bad)}, which is not a live agent of this episode")
        command = np.zeros((self.n_robots, 2))
        if not rows:
            return command
        # Each action's own dtype: numpy would promote a bool action among float ones to float.
        dtypes = {getattr(action, "dtype", None) for action in actions.values()}  # usually one
        values = None
        if all(d is not None and d.kind in "fiu" for d in dtypes):
            try:
                values = np.array(list(actions.values()), dtype=np.float32)  # as before: real dtypes only here
            except ValueError:  # shapes that do not stack
                values = None
            if values is not None and (values.shape != (len(rows), 2) or not (np.abs(values) <= 1.0).all()):
                values = None  # NaN fails the range test too
        if values is None:
            values = np.stack([self.check_agent_action(agent, action) for agent, action in actions.items()])
        command[rows] = values
        return command

    def check_agent_action(self, agent, action) -> np.ndarray:
        """``agent``'s action as a float32 array, or ``ValueError`` naming the agent: it must be real numbers (not
        complex, bool, string or object), without NaN, in the agent's action space."""
        try:
            value = real_array("action", action, np.float32)
            return check_action(self.action_spaces[agent], value)
        except ValueError as exc:
            raise ValueError(f"action for {show(agent)}: {exc}") from None

    def state(self) -> np.ndarray:
        """Global state: per robot x, y (m), cos and sin of the heading, and 1 while it is in the episode."""
        h = self.pose[:, 2]
        rows = np.column_stack([self.pose[:, :2], np.cos(h), np.sin(h), self.active]).astype(np.float32)
        return rows.reshape(-1)

    def render(self):
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if not self._started:
            raise ResetNeeded("call reset() before render()")
        from polyenvs.swarm.rendering import SwarmRenderer

        if self._renderer is None:
            self._renderer = SwarmRenderer(self.render_mode, self.metadata["render_fps"], self.layout.bounds)
        return self._renderer.render(self)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # --- metrics ----------------------------------------------------------------------------------------------
    def episode_metrics(self) -> dict[str, float]:
        """The swarm's metrics so far: fraction of robots at the goal, contact events (all robots), mean time to
        the goal (robots not there count the time so far), smallest clearance, robots stopped short of the goal,
        and (formation) the mean formation error over the steps."""
        metrics = {
            "success_rate": float(self._track[:, ARRIVED].mean()),
            "collisions": float(self._track[:, COLLISIONS].sum()),
            "time_to_goal_s": float(self._track[:, TIME_TO_GOAL].mean()),
            "min_clearance_cm": float(100.0 * self._track[:, MIN_CLEARANCE].min()),
            "stopped": float(self._stopped().sum()),
        }
        if self.formation:
            steps = self._formation_steps
            metrics["formation_error"] = self._formation_total / steps if steps else 0.0
        return metrics

    def _stopped(self) -> np.ndarray:
        window = max(1, round(STOPPED_WINDOW_S / self.control_period_s))
        return (self._track[:, STILL] >= window) & (self._track[:, ARRIVED] == 0)

    def _update_metrics(self) -> None:
        if self.formation:
            live = self.active.astype(bool)
            per_robot, swarm = self._formation_error()
            self._formation_now = per_robot.copy()
            self._formation_sum += np.where(live, per_robot, 0.0)
            self._formation_total += float(swarm)
            self._formation_steps += 1
            if self.num_cycles:
                self._rewards[:, 3] = np.where(live, -FORMATION_PENALTY * per_robot, 0.0)

    # --- sensing ----------------------------------------------------------------------------------------------
    def _sense(self, normals: np.ndarray, floor: np.ndarray) -> np.ndarray:
        """Run the sensing kernel and build every robot's observation row (a fresh array) with the noise draws
        ``normals`` ``(N, 11 + 2k)`` and ``floor`` ``(N, 4)`` (see :func:`polyenvs.swarm.sensors.write_observations`)."""
        g = self._grid
        core.build_grid(self.pose, self.active, *g.arrays)
        core.sense(self.pose, self.active, self._all_rows, self._sense_params, self._angles, self._walls, self._circles, *g.arrays,
                   self._beams, self._nb_index, self._nb_range, self._clearance)  # fmt: skip
        obs = np.empty((self.n_robots, self._obs_size), dtype=np.float32)
        ir.write_observations(self.pose, self.active, self._beams, self._nb_index, self._nb_range, self.goal[None],
                              self.n_robots, self._powers, normals, floor, self._observe_params, self._leader_at,
                              obs)  # fmt: skip
        return obs

    def _infos(self, index) -> dict:
        """Per-robot info: true pose, contacts, goal distance, the AP-lite diagnostics the paper plots, reward
        terms and the robot's episode metrics (a nested ``episode_metrics`` dict, or with ``flat_info`` the keys
        ``episode_<metric>``). Built from per-step columns (fresh arrays; rows are views of them)."""
        stopped = self._stopped()
        columns = [
            list(self.pose.copy()),
            self._track[:, COLLISIONS].astype(np.int64).tolist(),
            self._track[:, DISTANCE].tolist(),
            list(np.minimum(100.0 * self._beams, ir.IR_MAX_CM)),
            list(100.0 * self._powers),
            np.degrees(self._track[:, TURN]).tolist(),
            stopped.tolist(),
            *self._rewards.T.tolist(),
        ]
        metric_columns = [
            self._track[:, ARRIVED].tolist(),
            self._track[:, COLLISIONS].tolist(),
            self._track[:, TIME_TO_GOAL].tolist(),
            (100.0 * self._track[:, MIN_CLEARANCE]).tolist(),
            stopped.astype(np.float64).tolist(),
        ]
        if self.formation:
            columns.append(self._formation_now.tolist())
            metric_columns.append((self._formation_sum / max(self.num_cycles, 1)).tolist())
        index = list(index)
        if len(index) != self.n_robots:  # a subset: select the rows of every column first
            columns = [[column[i] for i in index] for column in columns]
            metric_columns = [[column[i] for i in index] for column in metric_columns]
        keys, metric_keys = self._info_keys, self.metric_names
        names = self.possible_agents
        if self.flat_info:  # fixed keys of numbers only, from the first reset on (TorchRL's PettingZooWrapper)
            keys = (*keys, *(f"episode_{name}" for name in metric_keys))
            rows = zip(*columns, *metric_columns, strict=True)
            return {names[i]: dict(zip(keys, row, strict=True)) for i, row in zip(index, rows, strict=True)}
        infos = {}
        for i, row, metric_row in zip(
            index, zip(*columns, strict=True), zip(*metric_columns, strict=True), strict=True
        ):
            info = dict(zip(keys, row, strict=True))
            info["episode_metrics"] = dict(zip(metric_keys, metric_row, strict=True))
            infos[names[i]] = info
        return infos

    @property
    def _info_keys(self) -> tuple[str, ...]:
        keys = ("pose", "collisions", "distance_to_goal_m", "nearest_obstacle_cm", "motor_powers", "turning_angle_deg",
                "stopped", *(f"reward_{name}" for name in self.reward_names))  # fmt: skip
        return (*keys, "formation_error") if self.formation else keys


def observation_structure(n_neighbours: int, formation: bool) -> dict[str, tuple[int, int]]:
    """Name -> (start, stop) of each part of a robot's observation (the baselines read it, not magic indices)."""
    k = n_neighbours
    structure = {"ir": (0, 4), "light": (4, 6), "neighbours": (6, 6 + 3 * k)}
    size = 6 + 3 * k
    if formation:
        structure["leader"] = (size, size + 3)
        structure["is_leader"] = (size + 3, size + 4)
        size += 4
    structure["powers"] = (size, size + 2)
    return structure


def structure_for(dim: int) -> dict[str, tuple[int, int]]:
    """The observation structure of a ``dim``-long observation (plain: 8 + 3k, formation: 12 + 3k)."""
    formation = (dim - 8) % 3 != 0
    k = (dim - (12 if formation else 8)) // 3
    if k < 1 or (dim - (12 if formation else 8)) % 3:
        raise ValueError(f"an observation of length {dim} is not a swarm robot's")
    return observation_structure(k, formation)


def _copy_box(box: spaces.Box) -> spaces.Box:
    return spaces.Box(box.low.copy(), box.high.copy(), dtype=box.dtype)


class SwarmAECEnv(parallel_to_aec_wrapper):
    """The AEC form of a swarm (PettingZoo's ``parallel_to_aec``), checking each action when its agent gives it.

    PettingZoo's conversion stores the actions and checks nothing until the last agent of the cycle has acted,
    when the parallel step rejects the batch: the error then comes at another agent's turn, and the bad action
    stays stored, so every later step raises until a reset. Here a live agent's action is checked at once
    (:meth:`SwarmEnv.check_agent_action`: real numbers in its space, NaN refused, the agent named) and a rejected
    one changes nothing: the same agent is still to act, as if the call had not been made. ``step`` and
    ``render`` before the first ``reset`` raise ``gymnasium.error.ResetNeeded``, as the parallel form does.
    """

    def __init__(self, parallel_env: SwarmEnv):
        super().__init__(parallel_env)
        self._started = False

    def reset(self, seed=None, options=None):
        super().reset(seed=seed, options=options)  # the parallel reset checks everything before it changes anything
        self._started = True

    def step(self, action):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            action = self.env.check_agent_action(agent, action)
        elif action is not None:  # PettingZoo's convention, checked by an assert there
            raise ValueError(f"{show(agent)} has left the episode: its step takes None, got {show(action)}")
        super().step(action)


class SwarmOrderEnforcingWrapper(OrderEnforcingWrapper):
    """PettingZoo's order-enforcing wrapper with the swarm's errors: ``step`` or ``render`` before the first
    ``reset`` raise ``gymnasium.error.ResetNeeded`` (PettingZoo's raises ``AssertionError``), and a ``reset`` that
    raises (unknown options) leaves the wrapper's bookkeeping as it was."""

    def reset(self, seed=None, options=None):
        flags = self._has_reset, self._has_updated
        try:
            super().reset(seed=seed, options=options)
        except Exception:
            self._has_reset, self._has_updated = flags
            raise

    def step(self, action):
        if not self._has_reset:
            raise ResetNeeded("call reset() before step()")
        super().step(action)

    def render(self):
        if not self._has_reset:
            raise ResetNeeded("call reset() before render()")
        return super().render()

    def __str__(self) -> str:
        return str(self.env)


def module_constructors(env_class: type[SwarmEnv]):
    """A task module's PettingZoo constructors, ``parallel_env, raw_env, env = module_constructors(TaskEnv)``:
    the parallel environment, the AEC form without wrappers (:class:`SwarmAECEnv`), and the AEC form with the
    order-enforcing wrapper (:class:`SwarmOrderEnforcingWrapper`)."""

    def parallel_env(**kwargs) -> SwarmEnv:
        return env_class(**kwargs)

    def raw_env(**kwargs) -> SwarmAECEnv:
        return SwarmAECEnv(env_class(**kwargs))

    def env(**kwargs) -> SwarmOrderEnforcingWrapper:
        return SwarmOrderEnforcingWrapper(raw_env(**kwargs))

    parallel_env.__doc__ = f"The PettingZoo parallel environment (keywords: see :class:`{env_class.__name__}`)."
    raw_env.__doc__ = "The AEC form, without wrappers (actions checked when given)."
    env.__doc__ = "The AEC form with the order-enforcing wrapper."
    return parallel_env, raw_env, env
