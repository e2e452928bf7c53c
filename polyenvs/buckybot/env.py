"""The Gymnasium surface shared by the Buckybot tasks: spaces, seeding, reset options, info, rendering.

Everything inside works on a batch of robots ("rows"), like the simulator: ``BuckybotEnv`` is a
:class:`polyenvs.core.rows.RowsEnv`, so a Gymnasium env is a batch of one and each task's ``VectorEnv`` (a
:class:`~polyenvs.core.rows.RowsVectorEnv`) runs the same class with many rows, and
the task equations exist once, in compiled kernels. The base knows no task and owns everything tasks share: the
physics advance, the base metrics (:data:`polyenvs.buckybot.simulator.BASE_METRICS`), the reward (the sum of the
task's reward terms) and the terminated column. A task module (:mod:`polyenvs.buckybot.goal` is the model) writes

- its declaration: ``REWARD_TERMS`` and ``METRICS`` (its own metrics; the base metrics come first), and
  ``OUT = BuckybotEnv.task_columns(REWARD_TERMS, METRICS)``, the :class:`polyenvs.core.columns.OutColumns` its
  column constants come from; ``task_observation_sizes`` (name -> size of each observation part after the
  sensors), with their bounds;
- two per-row functions, compiled: ``_score_row(b, sim, task, out)`` scores robot ``b`` after its tip (its reward
  terms and own metrics into ``out[b]``, its observation part into ``sim[S.A_OBS][b]``) and returns whether its
  episode terminated; ``_start_row(b, sim, task, out)`` does the same for a freshly placed robot (after its first
  readings; ``out[b]`` is zero). ``sim`` is the tuple of :data:`polyenvs.buckybot.simulator.SIM_ARRAYS`, ``task``
  the task's own tuple (``_task_arrays()``);
- its compiled step and reset, one line each, which hand those functions to the family's drivers::

      @njit(cache=True)
      def _step_kernel(actions, kernel):
          step_task(actions, kernel, _score_row, REWARD_TERMS)

  (and ``reset_task(rows, kernel, _start_row, REWARD_TERMS)``; numba inlines the drivers, so the task's call is
  compiled and cached with the task), set on the class as ``staticmethod``s;
- ``_task_init()`` and ``_task_arrays()``: the task's own arrays (after replacing one, call ``_repack_task()``),
  and optional hooks for per-plan tables (``_task_install_plan``) and per-episode choices (``_task_sample`` /
  ``_task_commit``).

A reset is a transaction (the convention of :mod:`polyenvs.core.rows`): every random choice is drawn and every
option validated on a copy of the generator before anything is written, so a call that raises leaves the
environment exactly as it was.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot import simulator as S
from polyenvs.buckybot.floor_plans import (
    LAYOUT_SPLIT,
    MAX_RANDOM_SEGMENTS,
    RANDOM_ROOM_BOUNDS,
    layout_plan,
    make_floor_plan,
    plan_width,
    random_room,
)
from polyenvs.buckybot.simulator import (
    BuckybotParams,
    BuckybotSimulator,
    advance_rows,
    first_sense_row,
    write_base_metrics,
)
from polyenvs.core.columns import OutColumns, spans, write_reward
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.geometry2d import pack_segments
from polyenvs.core.jit import compiled_for, njit
from polyenvs.core.layouts import check_layouts
from polyenvs.core.parameters import SharedVersionHistory, physical_parameters
from polyenvs.core.rows import RowsEnv, read_only, vector_convention
from polyenvs.core.validation import check_action, check_options, show
from polyenvs.core.window import check_window_scale

__all__ = [
    "GROUND_TRUTH_STRUCTURE",
    "SENSOR_OBSERVATION_STRUCTURE",
    "BuckybotAction",
    "BuckybotEnv",
    "PathTrail",
    "ground_truth_parts",
    "reset_task",
    "step_task",
]


class BuckybotAction(enum.IntEnum):
    """The three tips, in the resting face's frame (azimuths counter-clockwise from above).

    | value | name | frame azimuth | meaning |
    |-------|------|---------------|---------|
    | 0 | BACK | 0° | over the edge the robot last tipped over: undoes the previous tip |
    | 1 | FORWARD_RIGHT | 120° | 60° to the right of straight ahead (ahead = 180°, away from the last tip) |
    | 2 | FORWARD_LEFT | 240° | 60° to the left of straight ahead |
    """

    BACK = 0
    FORWARD_RIGHT = 1
    FORWARD_LEFT = 2


#: Layout of the sensor part of every Buckybot observation: name -> (start, stop) indices (the simulator's).
SENSOR_OBSERVATION_STRUCTURE = S.SENSOR_OBSERVATION_STRUCTURE
#: Layout of ``info["ground_truth"]``: name -> (start, stop) indices (the simulator's ``GROUND_TRUTH``).
GROUND_TRUTH_STRUCTURE = S.GROUND_TRUTH_STRUCTURE


def ground_truth_parts(ground_truth: np.ndarray) -> dict[str, np.ndarray]:
    """Named views of ``info["ground_truth"]``, one robot's ``(16,)`` or a vector env's ``(num_envs, 16)``:
    ``pose`` and ``dead_reckoned_pose`` (x cm, y cm, heading of frame direction 0 in degrees),
    ``tip_directions_deg``, ``true_range_cm`` and ``wall_distance_cm`` (one value per robot)."""
    return {
        name: ground_truth[..., start] if stop == start + 1 else ground_truth[..., start:stop]
        for name, (start, stop) in GROUND_TRUTH_STRUCTURE.items()
    }


@njit(inline="always")
def step_task(actions, kernel, score_row, terms):
    """A task's compiled step: advance every robot whose action is >= 0 (a row given -1 was just reset: it neither
    moves nor scores), then score each with ``score_row(b, sim, task, out)`` (returns terminated) and write its base
    metrics, its reward (the sum of its ``terms``, the task's reward term names) and its terminated flag.

    Inlined into the task's own cached ``_step_kernel``, where ``score_row`` is a global compiled function: numba
    can cache neither a function taking another as an argument nor a closure, but it caches this. The cache is
    checked against the task's file only: after editing a driver, delete the caches (:mod:`polyenvs.core.jit`)."""
    sim, out, task = kernel.sim, kernel.out, kernel.task
    advance_rows(actions, sim)
    state = sim[S.A_STATE]
    for b in range(actions.shape[0]):
        if actions[b] >= 0:
            terminated = score_row(b, sim, task, out)
            write_base_metrics(b, state, out, len(terms))
            write_reward(b, out, len(terms), terminated)


@njit(inline="always")
def reset_task(rows, kernel, start_row, terms):
    """A task's compiled reset of freshly placed robots ``rows``: their first readings, a zero ``_out`` row, then
    ``start_row(b, sim, task, out)`` (the task's start; returns terminated), the base metrics, the reward and the
    terminated flag, as :func:`step_task`."""
    sim, out, task = kernel.sim, kernel.out, kernel.task
    state = sim[S.A_STATE]
    for n in range(rows.shape[0]):
        b = rows[n]
        first_sense_row(b, sim)
        out[b, :] = 0.0
        terminated = start_row(b, sim, task, out)
        write_base_metrics(b, state, out, len(terms))
        write_reward(b, out, len(terms), terminated)


#: Actuator letters each action extends, by (face, edge at frame direction 0).
_ACTUATOR_NAMES = [
    ["".join(geo.ACTUATOR_LETTERS[geo.FACE_CORNER_ACTUATOR[f, (e0 + j) % 3]] for j in range(3)) for e0 in range(3)]
    for f in range(geo.N_FACES)
]
#: Face numbers (1-20) of the six observed range finders, by (face, edge at frame direction 0). The six upper
#: sensors repeat every 120° in pairs, so turning the frame by one edge shifts the list by two.
_SENSOR_FACES = [
    [tuple(int(v) + 1 for v in np.roll(geo.upper_sensor_faces()[0][f], -2 * e0)) for e0 in range(3)]
    for f in range(geo.N_FACES)
]
_INT_TYPES = (int, np.int64, np.int32, np.intp)
#: Points of the true and dead-reckoned paths kept for rendering (older points are dropped).
TRAIL_POINTS = 2000


class PathTrail:
    """The last ``TRAIL_POINTS`` true and dead-reckoned positions of one robot, for rendering (bounded memory)."""

    def __init__(self):
        self._points = np.zeros((TRAIL_POINTS, 4))
        self._count = 0

    def clear(self) -> None:
        self._count = 0

    def append(self, true_xy, dead_reckoned_xy) -> None:
        self._points[self._count % TRAIL_POINTS] = (*true_xy, *dead_reckoned_xy)
        self._count += 1

    def paths(self) -> tuple[np.ndarray, np.ndarray]:
        """(true, dead-reckoned) ``(n, 2)`` paths, oldest first."""
        n = min(self._count, TRAIL_POINTS)
        points = self._points[np.arange(self._count - n, self._count) % TRAIL_POINTS]
        return points[:, :2], points[:, 2:]


@dataclass
class _RowReset:
    """Everything a row's reset decided, drawn and validated before any state changes."""

    row: int
    rng: np.random.Generator
    plan: FloorPlan
    position: np.ndarray
    heading: float
    face: int
    task: Any
    reseeded: bool


#: The Version History every Buckybot task shares (:class:`~polyenvs.core.parameters.SharedVersionHistory`).
VERSION_HISTORY = """* v0: initial version (2026-11-22). Changed in place before any release, each time with the reference
  leaderboard regenerated: per-row random streams (2026-11-30) and the resets' draws from one uniform call each
  (start cell and point, heading, face, goal cell; 2026-11-30) give other episodes for the same seed. Added since
  without changing a default episode: the native vector env (``gym.make_vec``, 2026-11-22; both autoreset modes
  2026-11-30), every physical parameter as a validated keyword (2026-12-01), ``layouts=`` (held-out training and
  test layouts, 2026-12-02). ``info`` holds the ground truth as one array, ``info["ground_truth"]``, instead of an
  entry per part, and the actuator and sensor-face labels moved to ``env.frame_labels()`` (2026-12-02). ``info``
  made lean without changing an episode (2026-12-05): ``info["episode_metrics"]`` is only in the info of the step
  that ends the episode (terminated, or truncated by the env itself; on a native vector env's rows that end, time
  limit included), ``env.unwrapped.episode_metrics()`` returns them at any time, and
  :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates;
  a native vector env's ground-truth array is a read-only view valid until the next step or reset (copy it to
  keep it)."""


class BuckybotEnv(SharedVersionHistory, RowsEnv):
    """Base class of the Buckybot lattice environments (see the task classes for the full documentation)."""

    version_history = VERSION_HISTORY

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 4}
    #: Extra observation entries appended by a task: name -> size.
    task_observation_sizes: dict[str, int] = {}
    #: Bounds of the task's extra observation entries, in order.
    task_observation_low: tuple[float, ...] = ()
    task_observation_high: tuple[float, ...] = ()
    #: Reset options a task adds to "pose" and "face".
    task_option_names: tuple[str, ...] = ()
    #: The task's own floor plan (its ``floor_plan`` default); ``layouts="train"`` or ``"test"`` replaces it.
    default_floor_plan = "rectangle"
    #: How ``layouts=`` splits the plans (:data:`polyenvs.buckybot.floor_plans.LAYOUT_SPLIT`).
    layout_split = LAYOUT_SPLIT
    #: The robot's physical parameters, which the constructor takes as keywords (``**physical``).
    params_class: type[BuckybotParams] = BuckybotParams

    def __init__(self, *, floor_plan=default_floor_plan, layouts: str = "default", render_mode: str | None = None,
                 window_scale: float = 1.0, num_rows: int = 1, **physical):  # fmt: skip
        self._use_rows(num_rows)
        robot = physical_parameters(type(self), self.params_class, physical)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.noise_scale, self.range_noise_scale = robot.noise_scale, robot.range_noise_scale
        self.body_radius_cm = robot.body_radius_cm
        # A start this far from every wall leaves all three tips free: each lands one step away, the body needs
        # its radius.
        self.start_clearance_cm = self.body_radius_cm + geo.STEP_LENGTH_CM + 1.0
        self.layouts = self._check_layouts(layouts, floor_plan)
        # None: a plan drawn at every reset (a random room, or one of the layouts' distribution).
        self.floor_plan = make_floor_plan(floor_plan) if self.layouts == "default" else None
        if self.floor_plan is not None:
            self._check_plan(self.floor_plan, "floor_plan")
        self.render_mode = render_mode
        self.window_scale = check_window_scale(window_scale)

        n = self._batch_size
        self.sim = BuckybotSimulator(n, robot)
        self.action_space = spaces.Discrete(3)
        low = np.concatenate([np.zeros(S.N_SENSOR_OBS), self.task_observation_low]).astype(np.float32)
        high = np.concatenate([np.ones(S.N_SENSOR_OBS), self.task_observation_high]).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_structure = self.observation_parts()
        #: The parts of ``info["ground_truth"]``: name -> (start, stop).
        self.ground_truth_structure = GROUND_TRUTH_STRUCTURE

        # Plan slots: one plan shared by every row, or (random rooms in a vector env) one per row.
        self._n_slots = 1 if self.floor_plan is not None else n
        self._slot_plans: list[FloorPlan | None] = [None] * self._n_slots
        n_walls = len(self.floor_plan.segments) if self.floor_plan is not None else MAX_RANDOM_SEGMENTS
        self.sim.set_walls(np.zeros((self._n_slots, n_walls, 6)))
        #: The frame covers this box for the whole life of the instance (one frame size, whatever the room).
        self.view_bounds = self.floor_plan.bounds if self.floor_plan is not None else RANDOM_ROOM_BOUNDS

        self._allocate_rows()
        self._trail = PathTrail() if render_mode is not None else None
        self._renderer = None
        self._task_init()
        self._repack_task()

    # --- task interface ---------------------------------------------------------------------------------------
    #: Metrics every Buckybot task reports, before the task's own.
    base_metric_names = tuple(S.BASE_METRICS)

    @property
    def metric_names(self) -> tuple[str, ...]:
        return self.all_metric_names[len(self.base_metric_names) :]

    @classmethod
    def task_columns(cls, reward_names: tuple[str, ...], metric_names: tuple[str, ...]) -> OutColumns:
        """The ``_out`` columns of a task with these reward terms and own metrics (the base metrics first)."""
        return OutColumns(reward_names, cls.base_metric_names + tuple(metric_names))

    @classmethod
    def observation_parts(cls, task_sizes: dict[str, int] | None = None) -> dict[str, tuple[int, int]]:
        """The observation's layout, name -> (start, stop): the sensor part, then the task's parts
        (``task_observation_sizes`` unless ``task_sizes`` is given)."""
        sizes = cls.task_observation_sizes if task_sizes is None else task_sizes
        return spans({**S.SENSOR_OBSERVATION, **sizes})

    _step_kernel = None  # staticmethod: the task's compiled step, a call of step_task
    _reset_kernel = None  # staticmethod: the task's compiled reset, a call of reset_task

    def _task_init(self) -> None:
        """Allocate the task's arrays (``self._n_slots`` plan slots, ``self._batch_size`` rows)."""

    def _task_arrays(self) -> tuple:
        """The task's arrays, the tuple ``kernel.task`` both kernels take."""
        return ()

    def _repack_task(self) -> None:
        """Pack the kernels' arguments again from ``_task_arrays()`` (at construction, and after a task replaced
        one of its arrays)."""
        self._kernel_arrays = self._task_arrays()
        self._pack_kernel(self.sim.kernel_arrays(self._observations), self._kernel_arrays)

    _packed_names = (*RowsEnv._packed_names, "_compiled_step", "_row0_views", "_ground_truth_rows")

    def _pack_kernel(self, sim: tuple, task: tuple) -> None:
        super()._pack_kernel(sim, task)
        # Every step passes these two: their machine code is called without numba's per-call typing.
        self._compiled_step = compiled_for(self._step_kernel, self._actions, self._kernel)
        self._row0_views = self._info_views(0)  # made once: a single env's info reads them at every step
        # The vector env hands this over at every step (a single env copies its row: Gymnasium's checker refuses
        # an info sharing memory with the previous one).
        self._ground_truth_rows = read_only(self.sim.state[:, S.INFO_START : S.INFO_STOP])

    def _task_install_plan(self, slot: int, plan: FloorPlan) -> None:
        """Fill the task's tables for ``plan`` in plan slot ``slot``."""

    def _task_plan_usable(self, plan: FloorPlan) -> bool:
        """Whether a random room can host the task (rooms that cannot are redrawn)."""
        return True

    def _task_sample(self, plan: FloorPlan, position: np.ndarray, rng: np.random.Generator, options: dict) -> Any:
        """Validate the task's options and draw its per-episode choices (nothing may be written here)."""
        return None

    def _task_commit(self, row: int, sample: Any) -> None:
        """Store what ``_task_sample`` chose for ``row``."""

    def _vector_task_info(self) -> dict[str, np.ndarray]:
        """The task's own ``info`` entries for every row, as arrays (the vector env's form of ``_get_info``)."""
        return {}

    # --- helpers ----------------------------------------------------------------------------------------------
    def _check_layouts(self, layouts, floor_plan) -> str:
        """``layouts``, checked; "train" and "test" draw their own plans, so they refuse a ``floor_plan`` other than
        the task's default rather than ignore it."""
        layouts = check_layouts(layouts)
        own_plan = isinstance(floor_plan, str) and floor_plan == self.default_floor_plan
        if layouts != "default" and not own_plan:
            raise ValueError(
                f"layouts={layouts!r} draws its own floor plans: leave floor_plan at its default "
                f"({self.default_floor_plan!r}), or use layouts='default' with floor_plan={show(floor_plan)}"
            )
        return layouts

    def episode_layout(self) -> dict[str, float]:
        """Row 0's layout as :attr:`layout_split` classifies it: ``{"room width": cm}``."""
        return {"room width": plan_width(self.plan)}

    def _check_plan(self, plan: FloorPlan, name: str) -> None:
        if not plan.has_room(self.start_clearance_cm):
            raise ValueError(f"{name} leaves no room for the robot ({self.start_clearance_cm:.1f} cm from every wall)")

    def _slot(self, row: int) -> int:
        return 0 if self._n_slots == 1 else row

    @property
    def plan(self) -> FloorPlan | None:
        """Row 0's floor plan (``None`` before the first reset with ``floor_plan="random"``)."""
        return self._slot_plans[0] if self.floor_plan is None else self.floor_plan

    @property
    def position(self) -> np.ndarray:
        """Row 0's true position (cm)."""
        return self.sim.position[0].copy()

    # --- Gymnasium API (reset and step: RowsEnv's) ----------------------------------------------------------
    def _make_renderer(self):
        from polyenvs.buckybot.rendering import BuckybotRenderer

        return BuckybotRenderer(self.render_mode, self.metadata["render_fps"], self.view_bounds, self.window_scale)

    def action_masks(self) -> np.ndarray:
        """Tips that would not hit a wall (true geometry), for sb3-contrib's MaskablePPO."""
        return self.sim.state[0, S.ALLOWED : S.ALLOWED + 3] > 0.5

    def frame_labels(self, row: int = 0) -> dict[str, Any]:
        """What robot ``row``'s motion frame is on the body: ``actuators``, the actuator letter each action extends
        (a string of three letters A-L, in action order), and ``sensor_faces``, the faces (1-20) carrying the six
        observed range finders, in observation order."""
        face, edge0 = int(self.sim.state[row, S.FACE]), int(self.sim.state[row, S.EDGE0])
        return {"actuators": _ACTUATOR_NAMES[face][edge0], "sensor_faces": _SENSOR_FACES[face][edge0]}

    def get_keys_to_action(self) -> dict[tuple[int, ...], int]:
        """Keys for ``gymnasium.utils.play``: s = back, d = forward right, a = forward left."""
        return {(ord("s"),): BuckybotAction.BACK, (ord("d"),): BuckybotAction.FORWARD_RIGHT,
                (ord("a"),): BuckybotAction.FORWARD_LEFT}  # fmt: skip

    # --- the batched core (RowsEnv's interface, shared with the vector env) -----------------------------------
    def _check_action(self, action) -> int:
        if type(action) in _INT_TYPES and 0 <= action < 3:
            return int(action)  # the common case, checked without the space's slower generic test
        check_action(self.action_space, action)
        return int(action)

    def _check_actions(self, actions) -> np.ndarray:
        actions = np.asarray(actions)
        if (
            actions.shape != (self._batch_size,)
            or actions.dtype.kind not in "iu"
            or (actions < 0).any()
            or (actions > 2).any()
        ):
            raise ValueError(f"actions must be {self._batch_size} integers in {{0, 1, 2}}, got {actions!r}")
        return actions

    def _row_generator(self, row: int) -> np.random.Generator | None:
        return self.sim.streams.generators[row]

    def _row_steps(self) -> np.ndarray:
        return self.sim.state[:, S.STEPS]

    def _on_row0_step(self) -> None:
        if self._trail is not None:
            self._trail.append(self.sim.state[0, S.X : S.Y + 1], self.sim.state[0, S.DR_X : S.DR_Y + 1])
            if self.render_mode == "human":
                self.render()

    def _check_options(self, options) -> dict:
        return check_options(options, ("pose", "face", *self.task_option_names))

    def _prepare_row(self, row: int, rng: np.random.Generator, options: dict, reseeded: bool) -> _RowReset:
        """Draw and validate a new episode for ``row`` on ``rng`` (a new seed's generator if ``reseeded``, else
        a continuation of the row's own); writes nothing."""
        plan = self.floor_plan if self.floor_plan is not None else self._random_plan(rng)
        if "pose" in options:
            position, heading = self._option_pose(plan, options["pose"])
        else:
            position = plan.sample_start(rng, self.start_clearance_cm)
            heading = 2 * np.pi * rng.random()
        face = self._option_face(options["face"]) if "face" in options else int(geo.N_FACES * rng.random())
        task = self._task_sample(plan, position, rng, options)
        return _RowReset(row, rng, plan, position, heading, face, task, reseeded)

    def _commit_rows(self, resets: list[_RowReset]) -> None:
        """Install prepared episodes (nothing here raises), then sense and set up the task in one compiled call."""
        sim = self.sim
        for r in resets:
            slot = self._slot(r.row)
            if self._slot_plans[slot] is not r.plan:
                self._install_plan(slot, r.plan)
            sim.place_one(r.row, r.position, r.face, r.heading)
            sim.streams.restart(r.row, r.rng, r.reseeded)
            self._task_commit(r.row, r.task)
        rows = self._row0 if len(resets) == 1 and resets[0].row == 0 else np.array([r.row for r in resets])
        sim.streams.refill(rows)  # the first readings take a draw row
        self._reset_kernel(rows, self._kernel)
        self._started = True
        if self._trail is not None and 0 in rows:
            self._trail.clear()
            self._trail.append(sim.state[0, S.X : S.Y + 1], sim.state[0, S.DR_X : S.DR_Y + 1])

    def _install_plan(self, slot: int, plan: FloorPlan) -> None:
        walls = self.sim.walls
        walls[slot] = pack_segments(plan.segments, walls.shape[1])
        self._task_install_plan(slot, plan)
        self._slot_plans[slot] = plan

    def _advance(self, actions: np.ndarray) -> None:
        """Step every row whose action is >= 0 (rows with -1 were just reset: they neither move nor score)."""
        self.sim.streams.refill()
        step = self._compiled_step if actions is self._actions else self._step_kernel
        step(actions, self._kernel)

    def _option_pose(self, plan: FloorPlan, pose) -> tuple[np.ndarray, float]:
        try:
            x, y, heading_deg = (float(v) for v in pose)
        except (TypeError, ValueError):
            raise ValueError(f"reset option 'pose' must be (x_cm, y_cm, heading_deg), got {show(pose)}") from None
        position = np.array([x, y])
        if not np.isfinite(position).all() or not np.isfinite(heading_deg):
            raise ValueError(f"reset option 'pose' must be finite, got {show(pose)}")
        clearance = float(plan.clearance(position))
        if clearance < self.body_radius_cm:
            raise ValueError(
                f"reset option 'pose' puts the robot {clearance:.1f} cm from a wall "
                f"(inside or touching it; the body radius is {self.body_radius_cm:g} cm)"
            )
        if not plan.in_main_region(position):
            raise ValueError(f"reset option 'pose' ({x:g}, {y:g}) is outside the plan's free space")
        return position, math.radians(heading_deg)

    @staticmethod
    def _option_face(face) -> int:
        if isinstance(face, bool) or not isinstance(face, (int, np.integer)) or not 1 <= face <= geo.N_FACES:
            raise ValueError(f"reset option 'face' must be an integer 1..20, got {show(face)}")
        return int(face) - 1

    def _random_plan(self, rng: np.random.Generator) -> FloorPlan:
        """A random room (``floor_plan="random"``) or a plan of the ``layouts`` distribution, usable by the task."""
        for _ in range(100):
            plan = random_room(rng) if self.layouts == "default" else layout_plan(rng, self.layouts)
            if plan.has_room(self.start_clearance_cm) and self._task_plan_usable(plan):
                return plan
        raise RuntimeError("the random room generator failed to make a usable room")  # pragma: no cover

    def _info_views(self, row: int) -> tuple[np.ndarray, ...]:
        """Row ``row``'s state, its action mask, its ground-truth block and its reward terms, as views."""
        state = self.sim.state[row]
        terms = self._out[row, : len(self._reward_keys)]
        return state, state[S.ALLOWED : S.ALLOWED + 3], state[S.INFO_START : S.INFO_STOP], terms

    def _get_info(self, row: int) -> dict[str, Any]:
        # Few entries, two fresh arrays: building a dict of a dozen fresh arrays cost half a CartPole step.
        state, mask, truth, terms = self._row0_views if row == 0 else self._info_views(row)
        info = {
            "action_mask": mask.astype(np.int8),
            "ground_truth": truth.copy(),
            "face": int(state.item(S.FACE)) + 1,
            "blocked": state.item(S.BLOCKED) != 0.0,
        }
        info.update(zip(self._reward_keys, terms.tolist(), strict=True))
        return info

    def _vector_info(self, ended: np.ndarray) -> dict[str, Any]:
        """:meth:`_get_info` for every row, in Gymnasium's vector convention (the reward terms are views of one fresh
        array), with the metrics of the rows in ``ended``."""
        state = self.sim.state
        terms = self._out[:, : len(self._reward_keys)].copy()
        values: dict[str, Any] = {
            "action_mask": state[:, S.ALLOWED : S.ALLOWED + 3].astype(np.int8),
            "ground_truth": self._ground_truth_rows,
            "face": state[:, S.FACE].astype(np.int64) + 1,
            "blocked": state[:, S.BLOCKED] > 0.5,
        }
        for j, key in enumerate(self._reward_keys):
            values[key] = terms[:, j]
        values.update(self._vector_task_info())
        return vector_convention(values, self._metric_rows(), ended)
