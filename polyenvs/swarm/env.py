"""The PettingZoo surface shared by the swarm tasks: parameters, spaces, seeding, the agents' dictionaries.

A task (``corridor_v0``, ``obstacle_field_v0``, ``formation_v0``) subclasses :class:`SwarmEnv` and provides
``_fixed_layout`` (walls and view bounds, once per instance), ``sample_episode`` (obstacles, starts and goal,
drawn on the episode's generator at every reset) and ``sample_layout_episode`` (the same for ``layouts="train"`` and
``"test"``, whose split it declares with :func:`polyenvs.core.layouts.documents_layouts`); what it adds to the family's observation, rewards, metrics and
info it declares by name in its ``terms_class`` (:class:`polyenvs.swarm.batch.TaskTerms`). The simulation is
:class:`polyenvs.swarm.batch.SwarmBatch` with one environment (``env.batch``), the same core the vector envs run
with many: per step one noise draw and one compiled call per kernel over the robots; only the PettingZoo
dictionaries are built per agent.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils import OrderEnforcingWrapper
from pettingzoo.utils.conversions import parallel_to_aec_wrapper

from polyenvs.core import libm
from polyenvs.core.jit import njit
from polyenvs.core.layouts import LayoutSplit, check_layouts
from polyenvs.core.parameters import (
    SharedVersionHistory,
    check_parameters,
    documented,
    parameter,
    parameter_ranges,
    physical_parameters,
)
from polyenvs.core.validation import (
    check_action,
    check_bool,
    check_in_range,
    check_int,
    check_options,
    real_array,
    show,
)
from polyenvs.core.window import check_window_scale
from polyenvs.swarm.batch import (
    BEAM_M,
    INFO_DISTANCE,
    INFO_TERMS,
    INFO_TURN_DEG,
    LIGHT_REFERENCE_M,
    MAX_SPEED_FACTOR,
    METRIC_NAMES,
    REWARD_NAMES,
    STILL_M,
    STOPPED_WINDOW_S,
    SwarmBatch,
    TaskTerms,
)
from polyenvs.swarm.platforms import SENSOR_ANGLES_DEG, get_platform

__all__ = [
    "BEAM_M",
    "DEFAULT_COMM_RANGE_M",
    "Episode",
    "LIGHT_REFERENCE_M",
    "Layout",
    "MAX_SPEED_FACTOR",
    "PARAMETER_RANGES",
    "PETTINGZOO_PROBE_OPTION",
    "RobotRows",
    "STILL_M",
    "STOPPED_WINDOW_S",
    "SwarmAECEnv",
    "SwarmEnv",
    "SwarmOrderEnforcingWrapper",
    "check_swarm_options",
    "module_constructors",
    "observation_parts",
    "observation_structure",
    "structure_for",
]

#: The virtual sensor angles' plausible range (deg).
SENSOR_ANGLE_RANGE_DEG = (-90.0, 90.0)


@documented
@dataclass(frozen=True)
class SwarmParams:
    """The physical and sensing parameters every swarm task takes as keywords (a task may change a default: the
    obstacle field's rough terrain, for instance).

    {parameters}
    """

    control_period_s: float = parameter(
        0.1, 0.02, 1.0, "s", "ours: one control step; it must move a robot less than its radius"
    )
    full_speed_mps: float = parameter(0.5, 0.05, 1.0, "m/s", "ours: wheel speed at full power")
    terrain_noise: float = parameter(
        0.05, 0.0, 0.3, "", "ours: sd of the per-wheel speed factor per step; the per-episode drift has half of it"
    )
    ir_noise: float = parameter(0.03, 0.0, 0.2, "", "ours: relative IR reading noise")
    ir_raw_sd: float = parameter(2.0, 0.0, 20.0, "A/D units", "ours: raw IR reading noise")
    comm_range_m: float = parameter(3.0, 0.5, 10.0, "m", "ours: trilateration reach")
    range_noise_m: float = parameter(0.02, 0.0, 0.2, "m", "ours: trilateration range noise")
    bearing_noise_deg: float = parameter(2.0, 0.0, 20.0, "deg", "ours: trilateration bearing noise")
    light_noise_deg: float = parameter(2.0, 0.0, 20.0, "deg", "ours: light-bearing noise")
    goal_radius_m: float = parameter(
        0.4, 0.1, 3.0, "m", "ours: a robot this close to the light has arrived (a task may narrow the range)"
    )

    def __post_init__(self):
        check_parameters(self)


#: Plausible range of every parameter (from :class:`SwarmParams`); outside it: ValueError.
PARAMETER_RANGES = parameter_ranges(SwarmParams)
#: Trilateration reach when not given (m).
DEFAULT_COMM_RANGE_M = SwarmParams.comm_range_m

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
    """What a reset draws: obstacles ``(C, 3)`` (at most the task's ``n_obstacles``), start poses ``(N, 3)`` and
    the goal light ``(2,)``."""

    circles: np.ndarray
    starts: np.ndarray
    goal: np.ndarray


def _check_sensor_angles(sensor_angles_deg) -> tuple[float, ...]:
    try:
        angles = [check_in_range("sensor_angles_deg", a, *SENSOR_ANGLE_RANGE_DEG) for a in sensor_angles_deg]
    except TypeError:
        raise ValueError(f"sensor_angles_deg must be four angles, got {show(sensor_angles_deg)}") from None
    if len(angles) != 4 or sorted(angles) != angles:
        raise ValueError(
            f"sensor_angles_deg must be four increasing angles (S0 right-most), got {show(sensor_angles_deg)}"
        )
    return tuple(angles)


#: The v0 entry of the Version History every swarm task shares (:class:`~polyenvs.core.parameters.SharedVersionHistory`).
VERSION_HISTORY_V0 = """- v0: initial version (2026-11-30; in the registry 2026-12-01). Added since without changing a default
  episode: ``render_fps`` that follows the control period (one frame per step), the input rules of the other
  families (a step or render before the first reset raises ``ResetNeeded``, actions must be real numbers, unknown
  reset options raise), ``flat_info=True`` for TorchRL (2026-12-01), every parameter declared once with its range
  and source (2026-12-01), ``layouts=`` (held-out training and test layouts, 2026-12-02)."""
#: The Version History every swarm task shares: v0, then the lean ``info`` (issue 33's wording for the PettingZoo
#: envs).
VERSION_HISTORY = (
    VERSION_HISTORY_V0
    + """
- ``info`` made lean without changing an episode (2026-12-05): ``info["episode_metrics"]`` is only in each robot's
  info of the cycle that ends the episode (terminated, or truncated by the env itself; on a native vector env's rows
  that end, time limit included), ``env.episode_metrics()`` returns them at any time, and
  :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates;
  each robot's ``pose``, ``nearest_obstacle_cm`` and ``motor_powers`` are read-only views valid until the next step
  or reset (copy them to keep them). With ``flat_info=True`` the ``episode_<metric>`` keys stay in every info
  (TorchRL needs fixed keys)."""
)


class RobotRows:
    """The robots of a surface over a :class:`~polyenvs.swarm.batch.SwarmBatch` (its ``batch``), one row each: the
    PettingZoo environment's N, a vector env's E x N."""

    batch: SwarmBatch

    @property
    def pose(self) -> np.ndarray:
        """``(rows, 3)`` true poses: x, y (m), heading (rad). The simulation's own array."""
        return self.batch.pose

    @property
    def active(self) -> np.ndarray:
        """``(rows,)`` uint8: 1 while the row's robot is in its environment's episode. The simulation's own array."""
        return self.batch.active


class SwarmEnv(RobotRows, SharedVersionHistory, ParallelEnv):
    """Base class of the swarm tasks (see the task modules for the full documentation)."""

    version_history = VERSION_HISTORY

    metadata = {"render_modes": ["rgb_array", "human"], "name": "swarm", "is_parallelizable": True, "render_fps": 10}
    default_platform = "maxelbot"
    #: The most obstacles an episode places (a batch keeps that many slots per environment).
    n_obstacles = 0
    #: What the task adds to the family's observation, rewards, metrics and info (by name); the family's own
    #: tasks add nothing.
    terms_class: type[TaskTerms] = TaskTerms
    #: The task's physical and sensing parameters: :class:`SwarmParams`, or a subclass that changes a default or
    #: narrows a range (declared once there, for the validation, the constructor's default and the docstring).
    params_class: type[SwarmParams] = SwarmParams
    #: How ``layouts=`` splits the task's layouts (set by :func:`polyenvs.core.layouts.documents_layouts`).
    layout_split: LayoutSplit

    def __init__(  # noqa: PLR0913 - parallel_env's keywords: all keyword-only, one per documented argument
        self,
        *,
        layouts: str = "default",
        n_robots: int = 1,
        platform: str | None = None,
        max_cycles: int = 500,
        n_neighbours: int = 6,
        sensor_angles_deg=SENSOR_ANGLES_DEG,
        terminate_on_collision: bool = False,
        flat_info: bool = False,
        render_mode: str | None = None,
        window_scale: float = 1.0,
        **physical,
    ):
        self.layouts = check_layouts(layouts)
        self.n_robots = check_int("n_robots", n_robots, 1, 1024)
        self.platform = get_platform(self.default_platform if platform is None else platform)
        self.max_cycles = check_int("max_cycles", max_cycles, 1, 1_000_000)
        params = physical_parameters(type(self), self.params_class, physical)
        self.__dict__.update(dataclasses.asdict(params))
        self.n_neighbours = check_int("n_neighbours", n_neighbours, 1, 32)
        self.sensor_angles_deg = _check_sensor_angles(sensor_angles_deg)
        self.terminate_on_collision = check_bool("terminate_on_collision", terminate_on_collision)
        self.flat_info = check_bool("flat_info", flat_info)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.window_scale = check_window_scale(window_scale)
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
        self._build_spaces()
        #: The simulation: this environment as a batch of one.
        self.batch = SwarmBatch(self, 1)
        self._task_rewards = bool(self.terms_class.reward_names)  # a task's own terms: info keys of their own
        # The info keys a task adds after the family's (:func:`_family_infos`): its reward terms, its info.
        self._task_info_keys = (*(f"reward_{name}" for name in self.terms_class.reward_names),
                                *self.terms_class.info_names)  # fmt: skip
        self._views: tuple | None = None
        self._np_random_seed = None
        self._renderer = None
        self._started = False  # step() and render() need a first reset()

    def _build_spaces(self) -> None:
        """Agents, the observation structure, and one space object per agent (built once: action-space seeding
        then acts on what step() checks)."""
        n = self.n_robots
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agents: list[str] = []
        self.agent_name_mapping = {a: i for i, a in enumerate(self.possible_agents)}
        self._every_agent = list(range(n))
        parts = observation_parts(self.n_neighbours, self.terms_class.observation_parts)
        self.observation_structure = observation_structure(self.n_neighbours, self.terms_class.observation_parts)
        low = np.array([v for lows in parts.values() for v in lows], np.float32)
        obs_space = spaces.Box(low, np.ones(len(low), np.float32), dtype=np.float32)
        act_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
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

    # --- task interface ---------------------------------------------------------------------------------------
    def _task_init(self) -> None:
        """Check the task's own parameters (before the layout is built)."""

    def _fixed_layout(self) -> Layout:
        raise NotImplementedError

    def sample_episode(self, rng: np.random.Generator) -> Episode:
        """Draw an episode (obstacles, starts, goal) on ``rng``; the task's."""
        raise NotImplementedError

    def sample_layout_episode(self, rng: np.random.Generator, layouts: str) -> Episode:
        """Draw an episode of the ``layouts`` ("train" or "test") distribution on ``rng``; the task's."""
        raise NotImplementedError

    def draw_episode(self, rng: np.random.Generator) -> Episode:
        """The episode a reset draws on ``rng``: the task's own (``layouts="default"``) or one of its layouts."""
        if self.layouts == "default":
            return self.sample_episode(rng)
        return self.sample_layout_episode(rng, self.layouts)

    def episode_layout(self) -> dict[str, np.ndarray]:
        """The episode's layout as :attr:`layout_split` classifies it: ``{"obstacle radius": (C,) m}``."""
        return {"obstacle radius": self.circles[:, 2].copy()}

    # --- names and state ----------------------------------------------------------------------------------------
    @property
    def reward_names(self) -> tuple[str, ...]:
        """The reward terms, the family's then the task's (``info["reward_<name>"]`` each)."""
        return (*REWARD_NAMES, *self.terms_class.reward_names)

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The episode metrics, the family's then the task's."""
        return (*METRIC_NAMES, *self.terms_class.metric_names)

    @property
    def goal(self) -> np.ndarray:
        """The goal light ``(2,)`` (m)."""
        return self.batch.goals[0]

    @property
    def circles(self) -> np.ndarray:
        """The episode's obstacles ``(C, 3)``: x, y, radius (m)."""
        return self.batch.circles[0, : self.batch.n_circles[0]]

    @property
    def beams(self) -> np.ndarray:
        """``(N, 4)`` true distance (m) along each IR beam to what it hits, ``inf`` for nothing within reach."""
        return self.batch.beams

    @property
    def num_cycles(self) -> int:
        """Steps into the episode."""
        return int(self.batch.cycles[0])

    # --- PettingZoo API ---------------------------------------------------------------------------------------
    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        if self.batch.generators[0] is None:
            self.batch.generators[0], self._np_random_seed = seeding.np_random()
        return self.batch.generators[0]

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode. The swarm takes no reset options: ``options`` must be ``None`` or ``{}`` (anything else
        raises ``ValueError`` and changes nothing), save the key PettingZoo's own API tests probe with, ignored
        (see :func:`check_swarm_options`)."""
        check_swarm_options(options)
        if seed is not None:
            rng, used = seeding.np_random(seed)
        else:
            rng, used = self.np_random, self._np_random_seed
        self.batch.reset([0], [rng])
        self._np_random_seed = used
        self.agents = self.possible_agents[:]
        obs = self.batch.observations.copy()
        infos = self._infos(self._every_agent, [])
        self._started = True
        if self.render_mode == "human":
            self.render()
        return {a: obs[i] for i, a in enumerate(self.agents)}, infos

    def step(self, actions):
        if not self._started:
            raise ResetNeeded("call reset() before step()")
        command = self._command(actions)
        if not self.agents:
            # Every robot has left: nothing moves (SuperSuit's black_death wrapper steps once more with no actions).
            return {}, {}, {}, {}, {}
        batch = self.batch
        batch.step(command)
        obs = batch.observations.copy()
        truncate = self.num_cycles >= self.max_cycles
        agents = self.agents
        every = len(agents) == self.n_robots  # nobody has left (the common case): rows in agent order
        index = self._every_agent if every else [self.agent_name_mapping[a] for a in agents]
        reward = batch.step_rewards().tolist()
        term = batch.terminated.view(np.bool_).tolist()  # 0 or 1
        if every:
            observations, rewards = dict(zip(agents, obs, strict=False)), dict(zip(agents, reward, strict=False))
            terminations = dict(zip(agents, term, strict=False))
        else:
            observations = {a: obs[i] for a, i in zip(agents, index, strict=True)}
            rewards = {a: reward[i] for a, i in zip(agents, index, strict=True)}
            terminations = {a: term[i] for a, i in zip(agents, index, strict=True)}
        truncations = {a: not terminations[a] for a in agents} if truncate else dict.fromkeys(agents, False)
        ended = index if truncate else [i for i in index if term[i]] if True in term else []
        infos = self._infos(index, ended)
        self.agents = [] if truncate else [a for a in agents if not terminations[a]] if ended else agents
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _command(self, actions) -> np.ndarray:
        """The ``(N, 2)`` power fractions of a step's actions, all checked before anything changes. Actions must
        be real numbers: complex, bool, string and object input is refused, not cast. The common case (arrays of
        one real dtype and shape ``(2,)``) is one stacking and one compiled range test; anything else, or a batch
        that fails it, is checked agent by agent, which names the culprit."""
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict of agent -> action, got {show(actions)}")
        rows: list
        if len(actions) == len(self.agents) == self.n_robots and list(actions) == self.agents:
            rows = self._every_agent  # every robot, in order, all live (the common case)
        else:
            rows = [self.agent_name_mapping.get(agent) for agent in actions]
            live = self.batch.active.tolist()
            if any(i is None or not live[i] for i in rows):
                bad = next(a for a, i in zip(actions, rows, strict=True) if i is None or not live[i])
                raise ValueError(f"action for {show(bad)}, which is not a live agent of this episode")
        if not rows:
            return np.zeros((self.n_robots, 2))
        values = _stacked_actions(list(actions.values()))
        if values is None:
            values = np.stack([self.check_agent_action(agent, action) for agent, action in actions.items()])
        if rows == self._every_agent:  # every robot, in order (the common case)
            return values
        command = np.zeros((self.n_robots, 2))
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
        rows = np.column_stack([self.pose[:, :2], libm.cos(h), libm.sin(h), self.active]).astype(np.float32)
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
            self._renderer = SwarmRenderer(
                self.render_mode, self.metadata["render_fps"], self.layout.bounds, self.window_scale
            )
        return self._renderer.render(self)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # --- metrics and info -------------------------------------------------------------------------------------
    def episode_metrics(self) -> dict[str, float]:
        """The swarm's metrics so far: fraction of robots at the goal, contact events (all robots), mean time to
        the goal (robots not there count the time so far), smallest clearance, robots stopped short of the goal,
        then the task's own (its ``terms_class.metric_names``)."""
        return {name: float(value[0]) for name, value in self.batch.env_metrics().items()}

    def _infos(self, index: list[int], ended: list[int]) -> dict:
        """Per-robot info of the robots in ``index``: true pose, contacts, goal distance, the AP-lite diagnostics
        the paper plots, reward terms and the task's keys; and in the info of each robot in ``ended`` (its episode
        ended this cycle: it arrived, hit with ``terminate_on_collision``, or ``max_cycles`` truncated it) its
        episode metrics as a nested ``episode_metrics`` dict. With ``flat_info`` the metrics are the keys
        ``episode_<metric>`` of every info, for fixed keys (TorchRL). ``pose``, ``nearest_obstacle_cm`` and
        ``motor_powers`` are read-only views of the simulation, valid until the next step or reset (copy them to
        keep them); the other values are Python numbers."""
        batch = self.batch
        pose, nearest, powers = self._row_views()
        table = batch.info_table.T.tolist()
        columns = (pose, batch.info_collisions.tolist(), table[INFO_DISTANCE], nearest, powers, table[INFO_TURN_DEG],
                   batch.info_stopped.tolist())  # fmt: skip
        rows = _family_infos(columns, table[INFO_TERMS:])
        metrics = batch.robot_metrics() if self.flat_info or ended else {}
        if self._task_info_keys or self.flat_info:
            self._add_infos(rows, metrics)
        names = self.possible_agents
        infos = (
            dict(zip(names, rows, strict=True)) if len(index) == self.n_robots else {names[i]: rows[i] for i in index}
        )
        if ended and not self.flat_info:
            metric_columns = [value.tolist() for value in metrics.values()]
            for i in ended:
                infos[names[i]]["episode_metrics"] = {
                    name: column[i] for name, column in zip(metrics, metric_columns, strict=True)
                }
        return infos

    def _add_infos(self, rows: list[dict], metrics: dict[str, np.ndarray]) -> None:
        """The task's keys (its reward terms, its info) in each robot's info ``rows``, then with ``flat_info``
        the ``episode_<metric>`` keys of ``metrics``."""
        batch = self.batch
        keys, columns = list(self._task_info_keys), []
        if self._task_rewards:
            columns.extend(batch.rewards[:, len(REWARD_NAMES) :].T.tolist())
        columns.extend(
            value.tolist() if value.ndim == 1 else list(value) for value in batch.terms.robot_info().values()
        )
        if self.flat_info:  # fixed keys of numbers only, from the first reset on (TorchRL's PettingZooWrapper)
            keys.extend(f"episode_{name}" for name in metrics)
            columns.extend(value.tolist() for value in metrics.values())
        # A key at a time, as setitems (a sixth of the time of a row's update from a zip of its values); every
        # column has a value per row.
        for key, column in zip(keys, columns, strict=False):
            for row, value in zip(rows, column, strict=False):
                row[key] = value

    def _row_views(self) -> tuple[list, list, list]:
        """Each robot's rows of the batch's read-only info views (:meth:`SwarmBatch.robot_views`), made once."""
        if self._views is None:
            views = self.batch.robot_views()
            self._views = list(views["pose"]), list(views["nearest_obstacle_cm"]), list(views["motor_powers"])
        return self._views

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_views": None}  # views: a copy makes its own of its own arrays


def _stacked_actions(actions: list) -> np.ndarray | None:
    """The actions as one ``(len(actions), 2)`` float32 array when they are arrays of one real dtype, each of shape
    ``(2,)``, with values in [-1, 1]; else ``None`` (then each is checked on its own). The dtype is each action's
    own: numpy would promote a bool action among float ones to float."""
    try:
        dtypes = {action.dtype for action in actions}
    except AttributeError:  # not an array
        return None
    if len(dtypes) != 1:  # actions of several dtypes (rare)
        return None
    (dtype,) = dtypes
    if not (isinstance(dtype, np.dtype) and dtype.kind in "fiu"):
        return None
    try:
        values = np.array(actions, dtype=np.float32)
    except ValueError:  # shapes that do not stack
        return None
    return values if values.shape == (len(actions), 2) and _in_unit_box(values) else None


@njit(cache=True)
def _in_unit_box(values) -> bool:
    """Whether every value is in [-1, 1] (NaN is not): one compiled pass, a fraction of numpy's three calls."""
    for v in values.ravel():
        if not -1.0 <= v <= 1.0:
            return False
    return True


def _family_infos(columns: tuple, terms: list[list[float]]) -> list[dict]:
    """Each robot's info with the family's keys, from per-robot ``columns`` (pose, contact events, goal distance,
    nearest obstacle per beam, motor powers, turning angle, stopped) and the reward ``terms`` (``REWARD_NAMES``'
    order). The keys are written out: a dict display builds a 10-key dict in about a third of ``dict(zip(keys,
    row))``'s time, which at N = 20 is a sixth of a step."""
    progress, collision, arrival = terms
    return [
        {"pose": pose, "collisions": collisions, "distance_to_goal_m": distance, "nearest_obstacle_cm": nearest,
         "motor_powers": powers, "turning_angle_deg": turn, "stopped": stopped, "reward_progress": r_progress,
         "reward_collision": r_collision, "reward_arrival": r_arrival}
        for pose, collisions, distance, nearest, powers, turn, stopped, r_progress, r_collision, r_arrival
        in zip(*columns, progress, collision, arrival, strict=True)
    ]  # fmt: skip


def observation_parts(n_neighbours: int, task_parts: dict | None = None) -> dict[str, tuple[float, ...]]:
    """Name -> the lower bounds of its columns (every upper bound is 1), in observation order: the family's
    ``ir`` (4), ``light`` (bearing / pi, intensity), ``neighbours`` (range, bearing, mask per slot), then the
    task's own parts (``TaskTerms.observation_parts``), then ``powers`` (the last motor powers)."""
    parts = {"ir": (0.0,) * 4, "light": (-1.0, 0.0), "neighbours": (0.0, -1.0, 0.0) * n_neighbours}
    for name, lows in (task_parts or {}).items():
        if name in parts or name == "powers":
            raise ValueError(f"observation part {name!r} is the family's own")
        parts[name] = tuple(lows)
    parts["powers"] = (-1.0, -1.0)
    return parts


def observation_structure(n_neighbours: int, task_parts: dict | None = None) -> dict[str, tuple[int, int]]:
    """Name -> (start, stop) of each part of a robot's observation (the baselines read it, not magic indices)."""
    structure, start = {}, 0
    for name, lows in observation_parts(n_neighbours, task_parts).items():
        structure[name] = (start, start + len(lows))
        start += len(lows)
    return structure


def structure_for(dim: int, task_parts: dict | None = None) -> dict[str, tuple[int, int]]:
    """The observation structure of a ``dim``-long observation with the task's own ``task_parts`` (none: the
    family's parts only, 8 + 3k long); ``ValueError`` if no number of neighbour slots fits."""
    extra = sum(len(lows) for lows in (task_parts or {}).values())
    k, rest = divmod(dim - 8 - extra, 3)
    if k < 1 or rest:
        raise ValueError(f"an observation of length {dim} is not a swarm robot's")
    return observation_structure(k, task_parts)


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
