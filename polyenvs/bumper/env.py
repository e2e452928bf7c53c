"""The bump-only cart's family base, :class:`BumperCartEnv`, and its first task, ``polyenvs/BumperCartExplore-v0``
(touch as much of an unknown map's walls as possible).

The environment is a batch of carts ("rows") like the simulator, so a native vector env is the same class with
more rows. The base knows no task and owns what tasks share: one compiled call cycles every row that has an action
(:func:`polyenvs.bumper.cart.cycle_row`), writes the cycle's log (the observation's first parts), scores the row
with the task's compiled ``_score_row(b, sim, task, out)`` (its reward terms and own metrics into ``out[b]``; it
returns whether the episode terminated) and writes the base metrics (:data:`BASE_METRICS`, wherever the task
declares them), the reward (the sum of the task's terms) and the terminated column. A task subclasses
:class:`BumperCartEnv` with its declaration (``out_columns``, from its reward terms' and metrics' names),
``task_observation_sizes`` (with ``task_observation_low`` / ``_high``), the ``_task_*`` hooks below and its
compiled step, one line that hands ``_score_row`` to the base's driver::

    @njit(cache=True)
    def _step_kernel(actions, kernel):
        step_task(actions, kernel, _score_row, REWARD_TERMS)

(``staticmethod(_step_kernel)`` on the class). :class:`BumperCartExploreEnv` here is the model;
``polyenvs/bumper/localize.py`` runs Python between the cycle and the score (its filter draws from each row's
generator), so it cycles with :func:`cycle_rows` and scores with :func:`score_task`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from polyenvs.bumper import cart as C
from polyenvs.bumper.cart import CartModel, cycle_row, max_ticks, place_row
from polyenvs.bumper.maps import LAYOUT_MAX_SEGMENTS, LAYOUT_ROOM_BOUNDS, LAYOUT_SPLIT, BumperMap, layout_map, make_map
from polyenvs.bumper.odometry import TICK_CM
from polyenvs.core.columns import OutColumns, indices, spans, write_reward
from polyenvs.core.jit import compiled_for, njit
from polyenvs.core.layouts import check_layouts, documents_layouts
from polyenvs.core.parameters import documents_arguments, physical_parameters
from polyenvs.core.rows import RowsEnv, vector_convention
from polyenvs.core.streams import RowStreams
from polyenvs.core.validation import check_action, check_in_range, show
from polyenvs.core.window import check_window_scale

__all__ = [
    "BASE_METRICS",
    "LOG_SIZE",
    "OBSERVATION_STRUCTURE",
    "SIM_ARRAYS",
    "BumperCartEnv",
    "BumperCartExploreEnv",
    "LocalizationContext",
    "cycle_rows",
    "score_task",
    "step_task",
]

#: The parts of the cycle's log, every task's first observation parts: name -> size. Ticks are signed encoder
#: counts (left, right) of each stage of the cycle, in the order of the state's ``TICKS`` block; bump is 1 if the
#: drive stage ended with the bumper tripped.
OBSERVATION_PARTS = {"turn_ticks": 2, "drive_ticks": 2, "backup_ticks": 2, "bump": 1}
#: The same as name -> (start, stop).
OBSERVATION_STRUCTURE = spans(OBSERVATION_PARTS)
#: Entries of the cycle's log.
LOG_SIZE = OBSERVATION_STRUCTURE["bump"][1]
_TICKS_OBS, _TICKS_END = OBSERVATION_STRUCTURE["turn_ticks"][0], OBSERVATION_STRUCTURE["backup_ticks"][1]
_BUMP_OBS = OBSERVATION_STRUCTURE["bump"][0]
#: The metrics the base counts and writes for every task that declares them (among its ``metric_names``, anywhere):
#: the bumps, the dead-reckoning error (from the true start against the true position: the paper's Part 2 drift)
#: and the bumps that made the cart slip.
BASE_METRICS = ("bumps", "odometry_error_cm", "large_slips")
#: The arrays the compiled step takes, as one tuple ``sim`` in this order: the carts' state, the walls (a map slot
#: axis first), the parameters, the draw blocks and cursors, the observation rows, the cycles of each episode, the
#: base's tallies (bumps, large slips), the ``_out`` column of each base metric (-1 where the task has none), and
#: each row's info values (:data:`INFO_PARTS`, written by every cycle and reset) with the state columns they read.
SIM_ARRAYS = ("state", "walls", "params", "normals", "cursor", "obs", "cycles", "tallies", "base_columns", "info",
              "info_columns")  # fmt: skip
_SIM = indices(SIM_ARRAYS)
A_STATE, A_WALLS, A_PARAMS, A_NORMALS = _SIM["state"], _SIM["walls"], _SIM["params"], _SIM["normals"]
A_CURSOR, A_OBS, A_CYCLES = _SIM["cursor"], _SIM["obs"], _SIM["cycles"]
_A_TALLIES, _A_BASE_COLUMNS = _SIM["tallies"], _SIM["base_columns"]
_A_INFO, _A_INFO_COLUMNS = _SIM["info"], _SIM["info_columns"]
_BUMP_TALLY, _SLIP_TALLY = range(2)
#: Explore's reward term and metrics, by name (``info["reward_<term>"]``, ``info["episode_metrics"]``).
REWARD_TERMS = ("touch",)
METRICS = ("wall_fraction_touched", "bumps", "odometry_error_cm", "large_slips")
OUT = OutColumns(REWARD_TERMS, METRICS)
_R_TOUCH = OUT.term_column("touch")
_M_TOUCHED = OUT.metric_column("wall_fraction_touched")
#: Points of the paths kept for rendering (older ones are dropped, so memory stays bounded).
TRAIL_POINTS = 3000


#: State columns of the true, dead-reckoned and at-bump poses, as ``info`` reports them.
_POSE_COLUMNS = [C.X, C.Y, C.HEADING, C.DR_X, C.DR_Y, C.DR_HEADING, C.BUMP_X, C.BUMP_Y, C.BUMP_HEADING]
#: The info's pose and contact values, a row of the ``info`` table: name -> (start, stop).
INFO_PARTS = spans({"pose": 3, "dead_reckoned_pose": 3, "pose_at_bump": 3, "contact_point": 2})
_INFO_SIZE = INFO_PARTS["contact_point"][1]
#: Multiplies the poses' headings into degrees (``np.degrees``' own factor) and leaves the positions (and the
#: contact point after them) as they are.
_INFO_SCALE = np.array([1.0, 1.0, 180.0 / math.pi] * 3 + [1.0, 1.0])


def _real_array(value) -> np.ndarray | None:
    """``value`` as an array if it holds real numbers (a float or integer dtype), else ``None``: a complex turn
    would lose its imaginary part, and booleans, strings and objects would be cast to numbers silently."""
    if not isinstance(value, np.ndarray):
        try:
            value = np.asarray(value)
        except (TypeError, ValueError):  # ragged nesting
            return None
    return value if value.dtype.kind in "fiu" else None


@dataclass
class _RowReset:
    """Everything a row's reset decided, drawn and validated before any state changes."""

    row: int
    rng: np.random.Generator
    reseeded: bool
    world: BumperMap
    pose: np.ndarray
    mismatch: float
    wheel_base: float
    task: Any = None  # what the task's _task_prepare drew


@dataclass(frozen=True)
class LocalizationContext:
    """What a localizer may know before the first cycle: the map and the cart's nominal geometry.

    Attributes:
        world: the map.
        tick_cm: wheel travel per encoder tick.
        wheel_base_cm: the nominal wheel base the odometry uses.
        bumper_offset_cm, bumper_width_cm: where the bumper is, ahead of the axle, and how wide.
        observation_structure: where the ticks and the bump bit are in a cycle's log (the observation).
    """

    world: BumperMap
    tick_cm: float
    wheel_base_cm: float
    bumper_offset_cm: float
    bumper_width_cm: float
    observation_structure: dict


@njit(cache=True)
def _cycle(b, turn, sim):
    """Cycle row ``b`` by ``turn``, write the cycle's log into its observation row and tally its bump and slip.
    ``walls`` has a map slot axis first: one slot shared by every row, or one per row (``layouts="train"`` or
    ``"test"``)."""
    state, walls, params, normals, cursor, obs, cycles, tallies = sim[:8]
    row = state[b]
    cycle_row(row, turn, normals[b, cursor[b]], params, walls[0 if walls.shape[0] == 1 else b])
    cursor[b] += 1
    cycles[b] += 1.0
    for k in range(_TICKS_END - _TICKS_OBS):
        obs[b, _TICKS_OBS + k] = row[C.TICKS + k]
    obs[b, _BUMP_OBS] = row[C.BUMP]
    tallies[b, _BUMP_TALLY] += row[C.BUMP]
    tallies[b, _SLIP_TALLY] += row[C.BIG_SLIP]
    _write_info(row, sim[_A_INFO][b], sim[_A_INFO_COLUMNS])


@njit(cache=True)
def _write_info(row, info, columns):
    """A state row's info values (:data:`INFO_PARTS`: the poses, headings in degrees, and the credited contact) into
    ``info``, from the state ``columns`` they read: worked out once per cycle in compiled code, so that a single
    env's ``info`` is one copy of them."""
    for k in range(_INFO_SIZE):
        info[k] = row[columns[k]] * _INFO_SCALE[k]


@njit(cache=True)
def cycle_rows(actions, kernel):
    """Cycle every row that has an action (``actions[b, 1] >= 0.5``: a row that was just reset neither moves nor
    scores), without scoring it: a task that scores with :func:`score_task` calls this first."""
    for b in range(actions.shape[0]):
        if actions[b, 1] >= 0.5:
            _cycle(b, actions[b, 0], kernel.sim)


@njit(cache=True)
def _write_base_metrics(b, sim, out):
    """The :data:`BASE_METRICS` the task declares, into their columns of ``out[b]``."""
    row, tallies, columns = sim[A_STATE][b], sim[_A_TALLIES], sim[_A_BASE_COLUMNS]
    if columns[0] >= 0:
        out[b, columns[0]] = tallies[b, _BUMP_TALLY]
    if columns[1] >= 0:
        out[b, columns[1]] = math.hypot(row[C.X] - row[C.DR_X], row[C.Y] - row[C.DR_Y])
    if columns[2] >= 0:
        out[b, columns[2]] = tallies[b, _SLIP_TALLY]


@njit(inline="always")
def _finish_row(b, kernel, score_row, terms):
    """Score row ``b`` with the task's ``score_row``, then write its base metrics, reward and terminated flag."""
    terminated = score_row(b, kernel.sim, kernel.task, kernel.out)
    _write_base_metrics(b, kernel.sim, kernel.out)
    write_reward(b, kernel.out, len(terms), terminated)


@njit(inline="always")
def step_task(actions, kernel, score_row, terms):
    """A task's compiled step: cycle every row that has an action, then score it with ``score_row(b, sim, task,
    out)`` (returns terminated) and write its base metrics, its reward (the sum of its ``terms``, the task's reward
    term names) and its terminated flag.

    Inlined into the task's own cached ``_step_kernel``, where ``score_row`` is a global compiled function: numba
    can cache neither a function taking another as an argument nor a closure, but it caches this. The cache is
    checked against the task's file only: after editing a driver, delete the caches (:mod:`polyenvs.core.jit`)."""
    for b in range(actions.shape[0]):
        if actions[b, 1] >= 0.5:
            _cycle(b, actions[b, 0], kernel.sim)
            _finish_row(b, kernel, score_row, terms)


@njit(inline="always")
def score_task(actions, kernel, score_row, terms):
    """:func:`step_task` for rows :func:`cycle_rows` has cycled already: score them, without cycling."""
    for b in range(actions.shape[0]):
        if actions[b, 1] >= 0.5:
            _finish_row(b, kernel, score_row, terms)


@njit(cache=True)
def touch_row(b, row, touch) -> float:
    """Row ``b``'s share of the wall newly touched by its last cycle (its state row ``row``), marking the cell and
    adding it to the row's touched fraction and count. ``touch = (touched_fraction, touched, cell_first, cell_count,
    cell_share, credited, touched_count)``, as :class:`BumperCartExploreEnv` packs it (the cell tables with a map
    slot axis first, as the walls; ``credited`` the state column of the wall a bump credits)."""
    touched_fraction, touched, cell_first, cell_count, cell_share, credited, touched_count = touch
    w = 0 if cell_first.shape[0] == 1 else b
    fresh = 0.0
    if row[C.BUMP] > 0.5:
        seg = int(row[credited])
        count = cell_count[w, seg]
        cell = cell_first[w, seg] + min(max(int(row[C.CONTACT_ALONG] * count), 0), count - 1)
        if touched[b, cell] == 0:
            touched[b, cell] = 1
            touched_count[b] += 1
            fresh = cell_share[w, cell]
    touched_fraction[b] += fresh
    return fresh


@njit(cache=True)
def _score_row(b, sim, touch, out):
    """Row ``b`` after its cycle: the wall its bump newly touched (never terminates)."""
    out[b, _R_TOUCH] = 100.0 * touch_row(b, sim[A_STATE][b], touch)
    out[b, _M_TOUCHED] = touch[0][b]
    return False


@njit(cache=True)
def _step_kernel(actions, kernel):
    step_task(actions, kernel, _score_row, REWARD_TERMS)


class BumperCartEnv(RowsEnv):
    """Base class of the bump-only cart's tasks (see :class:`BumperCartExploreEnv` for the full documentation of
    what they share: the cart, the cycle, the log, the layouts, the starting state, the arguments).

    A task provides ``out_columns`` (its declaration: its reward terms' and metrics' names), the parts it adds
    to the observation after the log (``task_observation_sizes``, with per-entry bounds ``task_observation_low``
    and ``task_observation_high``), the reset options it takes (``task_option_names``), its compiled step
    (``_step_kernel``, see the module docstring) and the hooks ``_task_init`` (its arrays, once the map slots
    exist), ``_task_install_map`` (a map slot got a new room), ``_task_arrays`` (the tuple its step gets as
    ``task``), ``_task_prepare`` (draw a row's task on the reset's generator, writing nothing), ``_task_commit``
    (install it), ``_task_info`` / ``_vector_task_info`` (its ``info`` keys) and ``draw_task`` (its layer of a
    frame).
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 4}
    #: The task's observation parts after the log: name -> size, and the bounds of their entries in order.
    task_observation_sizes: dict[str, int] = {}
    task_observation_low: tuple[float, ...] = ()
    task_observation_high: tuple[float, ...] = ()
    #: Reset options the task takes besides ``pose``.
    task_option_names: tuple[str, ...] = ()
    #: The map of ``layouts="default"`` (the ``map`` keyword's default); other layouts draw their own rooms.
    default_map = "paper"
    #: How ``layouts="train"`` and ``"test"`` draw rooms (each task's docstring shows it with ``{layouts}``).
    layout_split = LAYOUT_SPLIT
    #: Whether a bump credits the cycle's latest contact instead of its own: the back-up's, when it touches a wall
    #: after the bump (a wall the bumper never touched). BumperCartExplore-v0 and -v1 did; they keep it, so that
    #: their results reproduce.
    credits_latest_contact = False
    #: The cart's physical parameters, which the constructor takes as keywords (``**cart``).
    params_class: type[CartModel] = CartModel
    _step_kernel = None  # staticmethod: the task's compiled step, a call of step_task

    def __init__(self, *, map=default_map, layouts: str = "default", render_mode: str | None = None,
                 window_scale: float = 1.0, num_rows: int = 1, **cart):  # fmt: skip
        self._use_rows(num_rows)
        self.model = physical_parameters(type(self), self.params_class, cart)
        self.start_clearance_cm = self.model.circumradius_cm + 0.5
        self.layouts = self._check_layouts(layouts, map)
        if self.layouts == "default":
            self.world = make_map(map, clearance_cm=self.start_clearance_cm)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.window_scale = check_window_scale(window_scale)

        n = self._batch_size
        self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        t = float(max_ticks(self.model))
        low = [-t] * 6 + [0.0, *self.task_observation_low]
        high = [t] * 6 + [1.0, *self.task_observation_high]
        self.observation_space = spaces.Box(np.array(low, dtype=np.float32), np.array(high, dtype=np.float32))
        self.observation_structure = {**OBSERVATION_STRUCTURE, **spans(self.task_observation_sizes, LOG_SIZE)}
        # A row's action is (turn in rad, 1); the base marks a row that gets none by writing NO_ACTION (-1) over it.
        self._allocate_rows(action_dtype=np.float64, action_shape=(2,))
        self._reward_items = tuple(enumerate(self._reward_keys))  # (its _out column, its info key): terms come first
        self.state = np.zeros((n, C.N_STATE))
        self.params = self.model.packed()
        self.streams = RowStreams(n, C.DRAWS_PER_CYCLE)
        self._cycles = np.zeros(n)
        self._tallies = np.zeros((n, 2))  # each episode's bumps and large slips
        self._info = np.zeros((n, _INFO_SIZE))
        #: The state columns the info values read: the poses, then the contact point.
        self._info_columns = np.array([*_POSE_COLUMNS, *self._contact_columns[:2]], dtype=np.int64)
        columns = self.out_columns
        base_columns = [columns.metric_column(name) if name in columns.metrics else -1 for name in BASE_METRICS]
        self._allocate_maps()
        arrays = dict(state=self.state, walls=self._walls, params=self.params, normals=self.streams.normals,
                      cursor=self.streams.cursor, obs=self._observations, cycles=self._cycles, tallies=self._tallies,
                      base_columns=np.array(base_columns, dtype=np.int64), info=self._info,
                      info_columns=self._info_columns)  # fmt: skip
        self._pack_kernel(tuple(arrays[name] for name in SIM_ARRAYS), self._task_arrays())
        self._renderer = None
        self._paths = (deque(maxlen=TRAIL_POINTS), deque(maxlen=TRAIL_POINTS), deque(maxlen=TRAIL_POINTS))

    def _check_layouts(self, layouts, map) -> str:
        """``layouts``, checked; "train" and "test" draw their own rooms, so they refuse a ``map`` other than the
        default rather than ignore it."""
        layouts = check_layouts(layouts)
        if layouts != "default" and not (isinstance(map, str) and map == self.default_map):
            raise ValueError(
                f"layouts={layouts!r} draws its own rooms: leave map at its default ({self.default_map!r}), or use "
                f"layouts='default' with map={show(map)}"
            )
        return layouts

    def _allocate_maps(self) -> None:
        """Map slots: the one map every row shares, or (other layouts) one room per row, installed at its reset.
        Walls ``(slots, S, 6)`` (zero rows pad a smaller room); then the task's arrays (:meth:`_task_init`)."""
        slots = 1 if self.layouts == "default" else self._batch_size
        n_walls = len(self.world.segments) if self.layouts == "default" else LAYOUT_MAX_SEGMENTS
        self._walls = np.zeros((slots, n_walls, 6))
        self._slot_worlds: list[BumperMap | None] = [None] * slots
        self._task_init()
        if self.layouts == "default":
            self._install_map(0, self.world)

    def _install_map(self, slot: int, world: BumperMap) -> None:
        """Put ``world``'s walls into map slot ``slot`` (padding: no wall), then the task's tables for it."""
        self._walls[slot] = 0.0
        self._walls[slot, : len(world.segments)] = world.walls
        self._slot_worlds[slot] = world
        self._task_install_map(slot, world)

    def _slot(self, row: int) -> int:
        return 0 if len(self._slot_worlds) == 1 else row

    @property
    def _contact_columns(self) -> tuple[int, int, int]:
        """The state columns (x, y, segment) of the contact a bump credits and ``info["contact_point"]`` shows."""
        if self.credits_latest_contact:
            return C.LATEST_X, C.LATEST_Y, C.LATEST_SEG
        return C.CONTACT_X, C.CONTACT_Y, C.CONTACT_SEG

    @property
    def world(self) -> BumperMap:
        """Row 0's map (with ``layouts="train"`` or ``"test"``, the room of its episode; ``None`` before a reset)."""
        return self._slot_worlds[0] if self.layouts != "default" else self._world

    @world.setter
    def world(self, value: BumperMap) -> None:
        self._world = value

    @property
    def map_bounds(self) -> tuple[float, float, float, float]:
        """A box holding every map this env can use: the map's bounds, or the layouts' room box."""
        return self.world.bounds if self.layouts == "default" else LAYOUT_ROOM_BOUNDS

    def episode_layout(self) -> dict[str, float]:
        """Row 0's layout as :attr:`layout_split` classifies it: ``{"room width": cm}``."""
        x0, _, x1, _ = self.world.bounds
        return {"room width": float(x1 - x0)}

    # --- the task's part ----------------------------------------------------------------------------------------
    def _task_init(self) -> None:
        """Allocate the task's per-row (and per map slot) arrays; the slots exist, the maps are not installed."""

    def _task_install_map(self, slot: int, world: BumperMap) -> None:
        """Map slot ``slot`` now holds ``world`` (at construction, or at a reset that drew a new room)."""

    def _task_arrays(self) -> tuple:
        return ()

    def _task_prepare(self, row: int, rng: np.random.Generator, world: BumperMap, pose: np.ndarray) -> Any:
        """Draw row ``row``'s task for the episode in ``world`` starting at ``pose`` on ``rng``, writing nothing
        (may raise)."""
        return None

    def _task_commit(self, row: int, sample: Any) -> None:
        """Install what :meth:`_task_prepare` drew (nothing here raises; the row's map is installed)."""

    def _task_info(self, row: int) -> dict[str, Any]:
        return {}

    def _vector_task_info(self) -> dict[str, np.ndarray]:
        return {}

    def draw_task(self, canvas) -> None:
        """Draw the task's layer of row 0's frame (under the paths and the cart)."""

    def _make_renderer(self):
        from polyenvs.bumper.rendering import BumperRenderer

        return BumperRenderer(self.render_mode, self.metadata["render_fps"], self.map_bounds, self.window_scale)

    def localization_context(self) -> LocalizationContext:
        """The map (row 0's) and the cart's nominal geometry, for estimators run on this environment's logs."""
        m = self.model
        return LocalizationContext(
            self.world, TICK_CM, m.wheel_base_cm, m.bumper_offset_cm, m.bumper_width_cm, dict(OBSERVATION_STRUCTURE)
        )

    # --- the batched core (:class:`polyenvs.core.rows.RowsEnv`) ----------------------------------------------
    def _check_options(self, options) -> dict:
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise ValueError(f"options must be a dict or None, got {show(options)}")
        allowed = ("pose", *self.task_option_names)
        if set(options) - set(allowed):
            raise ValueError(f"unknown reset option(s) {sorted(set(options) - set(allowed), key=str)}; expected "
                             f"{', '.join(map(repr, allowed))}")  # fmt: skip
        checked = {name: options[name] for name in self.task_option_names if name in options}
        if "pose" in options:
            checked["pose"] = self._option_pose(options["pose"])
        return checked

    def _option_pose(self, pose) -> np.ndarray:
        try:
            x, y, heading_deg = (float(v) for v in pose)
        except (TypeError, ValueError):
            raise ValueError(f"reset option 'pose' must be (x_cm, y_cm, heading_deg), got {show(pose)}") from None
        if not all(math.isfinite(v) for v in (x, y, heading_deg)):
            raise ValueError(f"reset option 'pose' must be finite, got {show(pose)}")
        if self.layouts == "default":  # other layouts check it against the room their reset draws
            self._check_pose(self.world, x, y)
        return np.array([x, y, math.radians(heading_deg)])

    def _check_pose(self, world: BumperMap, x: float, y: float) -> None:
        clearance = float(world.clearance(np.array([x, y])))
        if clearance < self.start_clearance_cm:
            raise ValueError(
                f"reset option 'pose' puts the cart {clearance:.1f} cm from a wall (at least "
                f"{self.start_clearance_cm:.1f} cm, its body's reach, in free space)"
            )

    def _draw_world(self, rng: np.random.Generator) -> BumperMap:
        """The episode's room for ``layouts="train"`` or ``"test"`` (redrawn in the rare room without space for
        the cart)."""
        for _ in range(100):
            world = layout_map(rng, self.layouts)
            if world.has_room(self.start_clearance_cm + 0.5):
                return world
        raise RuntimeError("the layout room generator failed to make a room the cart fits in")  # pragma: no cover

    def _prepare_row(self, row: int, rng: np.random.Generator, options: dict, reseeded: bool) -> _RowReset:
        world = self.world if self.layouts == "default" else self._draw_world(rng)
        if "pose" in options:
            pose = options["pose"]
            if self.layouts != "default":
                self._check_pose(world, pose[0], pose[1])
        else:
            pose = world.sample_pose(rng, self.start_clearance_cm)
        mismatch, wheel_base = self.model.draw_episode(rng)
        task = self._task_prepare(row, rng, world, pose)
        return _RowReset(row, rng, reseeded, world, pose, mismatch, wheel_base, task)

    def _commit_rows(self, prepared: list[_RowReset]) -> None:
        for r in prepared:
            slot = self._slot(r.row)
            if self._slot_worlds[slot] is not r.world:
                self._install_map(slot, r.world)
            place_row(self.state[r.row], r.pose, r.mismatch, r.wheel_base)
            self._compiled_write_info(self.state[r.row], self._info[r.row], self._info_columns)
            self.streams.restart(r.row, r.rng, r.reseeded)
            self._cycles[r.row] = 0.0
            self._tallies[r.row] = 0.0
            self._observations[r.row] = 0.0
            self._out[r.row] = 0.0
            self._task_commit(r.row, r.task)
            if r.row == 0:
                for path in self._paths:
                    path.clear()
                self._paths[0].append(tuple(r.pose[:2]))
                self._paths[1].append(tuple(r.pose[:2]))
        self._started = True

    _packed_names = (*RowsEnv._packed_names, "_compiled_step", "_compiled_write_info")

    def _pack_kernel(self, sim: tuple, task: tuple) -> None:
        super()._pack_kernel(sim, task)
        # Every step (and reset) passes these: their machine code is called without numba's per-call typing.
        self._compiled_step = compiled_for(self._step_kernel, self._actions, self._kernel)
        self._compiled_write_info = compiled_for(_write_info, self.state[0], self._info[0], self._info_columns)

    def _advance(self, actions: np.ndarray) -> None:
        self.streams.refill()
        step = self._compiled_step if actions is self._actions else self._step_kernel
        step(actions, self._kernel)

    def _row_generator(self, row: int) -> np.random.Generator | None:
        return self.streams.generators[row]

    def _row_steps(self) -> np.ndarray:
        return self._cycles

    def _check_action(self, action) -> tuple[float, float]:
        if (
            isinstance(action, np.ndarray)
            and action.shape == (1,)
            and action.dtype.kind == "f"
            and -1.0 <= action[0] <= 1.0
        ):
            turn = float(action[0])  # the common case, checked without the space's slower generic test
        else:
            array = _real_array(action)
            if array is None:
                raise ValueError(
                    f"action {show(action)} is not a turn in the action space {self.action_space} (a real number: "
                    "complex, boolean, string and object values are refused)"
                )
            array = array.astype(np.float32)
            check_action(self.action_space, array)
            turn = float(array[0])
        return math.pi * turn, 1.0

    def _check_actions(self, actions: np.ndarray) -> np.ndarray:
        array = _real_array(actions)
        if array is not None:
            array = array.astype(np.float32)
        if (
            array is None
            or array.shape != (self._batch_size, 1)
            or np.isnan(array).any()
            or (np.abs(array) > 1.0).any()
        ):
            raise ValueError(
                f"actions must be ({self._batch_size}, 1) turns in [-1, 1] (real numbers: complex, boolean, string "
                f"and object values are refused), got {show(actions)}"
            )
        return np.stack([math.pi * array[:, 0].astype(np.float64), np.ones(self._batch_size)], axis=1)

    def _on_row0_step(self) -> None:
        if self.render_mode is None:
            return
        s = self.state[0]
        true_path, dead_reckoned, bumps = self._paths
        true_path.extend(((s[C.TURN_X], s[C.TURN_Y]), (s[C.BUMP_X], s[C.BUMP_Y]), (s[C.X], s[C.Y])))
        dead_reckoned.append((s[C.DR_X], s[C.DR_Y]))
        if s[C.BUMP] > 0.5:
            x, y, _ = self._contact_columns
            bumps.append((s[x], s[y]))
        if self.render_mode == "human":
            self.render()

    def _get_info(self, row: int) -> dict[str, Any]:
        values = self._info[row].copy()  # one fresh array; the entries below are views of it
        info = {
            "pose": values[0:3],
            "dead_reckoned_pose": values[3:6],
            "pose_at_bump": values[6:9],
            "bumped": self.state.item(row, C.BUMP) > 0.5,
            "contact_point": values[9:11],
        }
        info.update(self._task_info(row))
        out = self._out
        for column, key in self._reward_items:
            info[key] = out.item(row, column)
        return info

    def _vector_info(self, ended: np.ndarray) -> dict[str, Any]:
        """:meth:`_get_info` for every row, in Gymnasium's vector convention, with the metrics of the rows in
        ``ended``."""
        table = self._info.copy()
        terms = self._out[:, self.out_columns.term_slice].copy()
        values = {
            "pose": table[:, 0:3],
            "dead_reckoned_pose": table[:, 3:6],
            "pose_at_bump": table[:, 6:9],
            "bumped": self.state[:, C.BUMP] > 0.5,
            "contact_point": table[:, 9:11],
            **self._vector_task_info(),
            **{key: terms[:, j] for j, key in enumerate(self._reward_keys)},
        }
        return vector_convention(values, self._metric_rows(), ended)


@documents_arguments(CartModel)
@documents_layouts(LAYOUT_SPLIT)
class BumperCartExploreEnv(BumperCartEnv):
    """Touch as much of an unknown map's walls as possible with a cart whose only sensors are a bumper and two
    wheel encoders.

    ## Description
    The Lego cart of Ken Dye's "Mapping with only a bumper": two unmatched motors (equal power drives an arc),
    encoders of 0.0675 in per tick on both axles, a 3-inch bumper over one switch. One step is one cycle of the
    paper's control loop: turn in place by the commanded angle, drive until the bumper trips (or
    ``max_drive_cm``), back up ``backup_cm``. Driving to the bump is solved in closed form against the map's wall
    segments (:mod:`polyenvs.bumper.cart`). Wheels slip a little on every stage and, at a bump, sometimes a lot
    (the bumper flattens against the wall or slides), unseen by the encoders. The agent sees what the robot logged
    and nothing else: it must build its own idea of where it is from ticks and bumps.

    ## Action Space
    ``Box(-1, 1, (1,), float32)``: the turn before driving, as a fraction of 180° (positive: counter-clockwise).
    The controller aims it with the nominal wheel base, so the turn done differs a little. A turn must be a real
    number (a float or integer array): complex, boolean, string and object values raise ``ValueError``.

    ## Observation Space
    ``Box((7,), float32)``: the signed encoder ticks (left, right) of the turn, the drive and the back-up, and 1.0
    if the drive ended in a bump (``env.observation_structure``). Ticks lie in ``[-T, T]`` with ``T`` from
    :func:`polyenvs.bumper.cart.max_ticks` (1,752 at the defaults). The reset observation is all zeros.

    ## Rewards
    ``reward_touch``: 100 x the wall length newly touched by this cycle's bump, as a fraction of the map's total
    wall length; walls are cut into cells of at most ``cell_cm`` and a bump touches the cell of its contact point,
    so an episode's rewards sum to at most 100.

    ## Starting State
    The cart at a uniformly random free point at least its body's reach from every wall, heading uniform; the
    motor mismatch and the true wheel base are drawn per episode (with ``layouts="train"`` or ``"test"``, after the
    episode's room). Reset option ``pose``: ``(x_cm, y_cm, heading_deg)``.

    ## Episode End
    Never terminates; truncated after ``max_episode_steps`` cycles (200 at registration). The metrics
    (``env.unwrapped.episode_metrics()`` at any time; under Gymnasium's time limit, the last ``info`` has them through
    :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics`): ``wall_fraction_touched``, ``bumps``,
    ``odometry_error_cm`` (dead reckoning from the true start against the true position: the paper's Part 2 drift),
    ``large_slips``. ``info`` also has the true ``pose``, ``dead_reckoned_pose`` and ``pose_at_bump`` (``(x_cm, y_cm,
    heading_deg)``; the last is where the drive stage ended), ``bumped``, ``contact_point`` (the last bump's, cm) and
    ``touched_cells``.

    ## Task score
    ``wall_fraction_touched`` (max, ceiling 1): the paper's cart maps a maze by bumping into its walls, and a wall
    it never touched is a wall missing from its map, so the score is the fraction of the wall length touched. The
    paper's own policy is the random bounce, and on this map coverage saturates within the 200 cycles: the score
    barely tells the bounce from a uniformly random turn (which is what it draws), a known weakness of this id.

    ## Arguments
    | argument | default | meaning |
    |----------|---------|---------|
    | map | "paper" | a name in :data:`polyenvs.bumper.maps.MAPS` or a list of polygons (outline first, cm) |
    {layouts}
    | cell_cm | 5.0 | wall cell length for the touch reward, in [1, 50] |
    {arguments}
    | render_mode | None | "rgb_array" or "human" |
    | window_scale | 1.0 | with render_mode="human", the window shows each frame zoomed by this factor, in [0.25, 8]; rgb_array frames are unchanged |
    | num_rows | 1 | rows simulated at once, an integer in [1, 1e6]: the native vector env sets it (``gym.make_vec``) |

    The physical parameters are :class:`polyenvs.bumper.cart.CartModel`'s.

    ## Version History
    * v0: initial version. Since 2026-12 the contact solution finds a body corner or a wall vertex that crosses a wall
      line a second time (it had missed it, letting the body into walls on maps with convex wall corners); the
      leaderboard's episodes (50 seeds, the paper map) are unchanged by it. Added since without changing a default
      episode: turns must be real numbers (complex, boolean and string actions raise), the parameters declared once with
      range and source (2026-12-01), ``layouts=`` (held-out training and test rooms, 2026-12-02), ``window_scale=``
      (2026-12-02); BumperCartExplore-v1 (a 50-cycle budget) is its successor for ranking. Known defect, kept so that
      its results reproduce (2026-12-05, issue 29): when the back-up touches a wall after the bump, that wall is
      credited (``touch``, ``wall_fraction_touched``, ``touched_cells``, ``contact_point``: the rear's contact, a wall
      the bumper never touched), in 0.1-0.35% of bumps; BumperCartExplore-v2 credits the bumper's. ``info`` made lean
      without changing an episode (2026-12-05): ``info["episode_metrics"]`` is only in the info of the step that ends
      the episode (terminated, or truncated by the env itself; on a native vector env's rows that end, time limit
      included), ``env.unwrapped.episode_metrics()`` returns them at any time, and
      :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` adds them where Gymnasium's ``TimeLimit`` truncates.
    """

    out_columns = OUT
    credits_latest_contact = True

    def __init__(self, *, map=BumperCartEnv.default_map, layouts: str = "default", cell_cm: float = 5.0,
                 render_mode: str | None = None, num_rows: int = 1, **cart):  # fmt: skip
        self.cell_cm = check_in_range("cell_cm", cell_cm, 1.0, 50.0)
        super().__init__(map=map, layouts=layouts, render_mode=render_mode, num_rows=num_rows, **cart)

    def _task_init(self) -> None:
        """Per map slot, each segment's first wall cell and cell count and each cell's share of the wall length;
        ``_touched`` marks each row's touched cells, ``_task`` sums their shares."""
        slots, n_walls = self._walls.shape[:2]
        if self.layouts == "default":
            n_cells = len(self.world.wall_cells(self.cell_cm)[2])
        else:
            x0, y0, x1, y1 = LAYOUT_ROOM_BOUNDS
            # Walls of a room in the box are at most its perimeter plus its boxes'; each wall adds < 1 cell.
            most_cm = 2 * (x1 - x0 + y1 - y0) * 2
            n_cells = int(math.ceil(most_cm / self.cell_cm)) + n_walls
        self._slot_cell_first = np.zeros((slots, n_walls), dtype=np.int64)
        self._slot_cell_count = np.zeros((slots, n_walls), dtype=np.int64)
        self._slot_cell_share = np.zeros((slots, n_cells))
        self._touched = np.zeros((self._batch_size, n_cells), dtype=np.uint8)
        self._task = np.zeros(self._batch_size)  # each row's touched wall fraction
        self._touched_count = np.zeros(self._batch_size, dtype=np.int64)  # and its touched cells

    def _task_install_map(self, slot: int, world: BumperMap) -> None:
        first, count, lengths = world.wall_cells(self.cell_cm)
        k = len(world.segments)
        # Unused segments start past the last cell, so each segment's first cell stays sorted.
        self._slot_cell_first[slot] = len(lengths)
        self._slot_cell_first[slot, :k], self._slot_cell_count[slot] = first, 0
        self._slot_cell_count[slot, :k] = count
        self._slot_cell_share[slot] = 0.0
        self._slot_cell_share[slot, : len(lengths)] = lengths / world.wall_length_cm

    @property
    def _cell_first(self) -> np.ndarray:
        """Row 0's map: each segment's first wall cell (the renderer and the tests read these)."""
        return self._slot_cell_first[self._slot(0)]

    @property
    def _cell_count(self) -> np.ndarray:
        return self._slot_cell_count[self._slot(0)]

    @property
    def _cell_share(self) -> np.ndarray:
        return self._slot_cell_share[self._slot(0)]

    def _task_arrays(self) -> tuple:
        cells = (self._slot_cell_first, self._slot_cell_count, self._slot_cell_share)
        return (self._task, self._touched, *cells, self._contact_columns[2], self._touched_count)

    def _task_commit(self, row: int, sample: Any) -> None:
        self._touched[row] = 0
        self._task[row] = 0.0
        self._touched_count[row] = 0

    _step_kernel = staticmethod(_step_kernel)

    def _task_info(self, row: int) -> dict[str, Any]:
        return {"touched_cells": self._touched_count.item(row)}

    def _vector_task_info(self) -> dict[str, np.ndarray]:
        return {"touched_cells": self._touched_count.copy()}

    def draw_task(self, canvas) -> None:
        from polyenvs.bumper.rendering import draw_touched_cells

        draw_touched_cells(canvas, self)
