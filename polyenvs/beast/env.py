"""The Gymnasium surface shared by the beast tasks, on Gymnasium's ``MujocoEnv`` (model loading, state, renderer).

A task subclasses :class:`BeastEnv` and provides ``reward_names`` and ``metric_names``, ``_initial_state`` (the
start state, drawn from the env's generator without touching the simulation), ``task_kind`` (its rules in the
compiled step, :mod:`polyenvs.beast.kernel`) and ``_task_reset`` (its state's start). A task written in Python
instead (the adding guide's) leaves ``task_kind`` 0 and provides ``_task_step`` (reward terms, termination, running
metrics, from the tick's :class:`~polyenvs.beast.sensors.StepSummary`), which the step calls tick by tick; the native
vector env runs compiled tasks only. Everything else lives here:

- the model is generated from the constructor's parameters (:mod:`polyenvs.beast.model`) and loaded through a
  temporary file, so nothing is shipped that cannot be regenerated;
- a step checks the action (raising ``ValueError`` before anything changes) and is one compiled call
  (:func:`polyenvs.beast.kernel.step_rows`): it writes the controls and runs the 10 ms sensor tick (``mj_step``
  ``frame_skip`` times, the sensors of :mod:`polyenvs.beast.sensors`, the task's rules) once per tick of the control
  period (``control_timestep``: the action is held, the ticks' rewards summed);
- a diverged simulation (non-finite or huge state) never reaches the user: the episode is truncated with
  ``info["sim_unstable"] = True``, the last finite observation and a zero reward;
- ``info`` holds the named reward terms (``reward_<name>``, summing to the reward) and ``sim_unstable``; the step
  that ends the episode (terminated, or truncated by a divergence) adds ``episode_metrics``, which
  :meth:`BeastEnv.episode_metrics` returns at any time (``polyenvs evaluate`` reports the final ones);
- the actuators' mechanical power of each tick (the summary's ``power``) makes the metrics :data:`POWER_METRICS`
  (and :data:`TRAVEL_METRICS` on a task that travels) of a task that lists them in its ``metric_names``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import tempfile

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from polyenvs.beast import kernel as KR
from polyenvs.beast import kinematics as K
from polyenvs.beast import model as M
from polyenvs.beast import sensors as S
from polyenvs.beast.layouts import LAYOUT_PARAMETERS, LAYOUT_SPLIT, ModelFields, draw_layout
from polyenvs.beast.model import CONTROL_DT
from polyenvs.beast.mujoco_extra import MujocoEnv, mujoco
from polyenvs.beast.vector import BeastVectorEnv
from polyenvs.core.jit import compiled_for
from polyenvs.core.layouts import check_layouts
from polyenvs.core.parameters import check_parameters, parameter, physical_parameters
from polyenvs.core.validation import check_bool, check_choice, check_options, real_array, show
from polyenvs.core.vector_entry import NativeVector

__all__ = ["POWER_METRICS", "TRAVEL_METRICS", "BeastEnv", "RobotContactParams", "SensorParams", "TumbleCounter"]

#: Ticks a support (set of feet on the floor) must hold to count as a stance: 0.2 s, as in the working tumble.
STANCE_TICKS = KR.STANCE_TICKS
#: The actuators' mechanical power over an episode, from each tick's (W): the mean over the ticks and the largest.
POWER_METRICS = ("mean_power_w", "peak_power_w")
#: The power metrics of a task that travels (one with ``distance_m``): those and the cost of transport, the energy
#: (the ticks' power times 10 ms, J) over the robot's weight (its bodies' masses, with the layout's, times MuJoCo's
#: gravity, N) times ``distance_m`` (m); 0 while ``distance_m`` is not positive, so that it stays finite.
TRAVEL_METRICS = (*POWER_METRICS, "cost_of_transport")
_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))
#: A drawn start state is rounded to 1e-9 (m, rad, m/s, rad/s): numpy's matrix products and transcendental functions
#: run CPU-specific kernels (OpenBLAS's per-core-type GEMM, AVX-512 or AVX2 SIMD sines) that differ in the last bit,
#: and a contact simulation grows a last-bit difference in the start into a different episode on another machine.
#: Rounding removes it (only a value within about 1e-16 of a rounding boundary can still differ); a state passed as
#: a reset option is used exactly as given.
START_DECIMALS = 9


#: Why the robot's contact model (the -v1 ids' defaults) has a servo dead band: paper section 2.
_DEADBAND_SOURCE = (
    "ours: a servo stops driving within this of its target and the worm drive, which does not backdrive, holds the "
    "joint (paper section 2: worm gears, backlash far above the encoder's resolution); half the 0.5 deg backlash"
)
#: Why it debounces the foot switches (the switches are ours, spec beast.md; the paper has none).
_DEBOUNCE_SOURCE = (
    "ours: firmware debounce of a mechanical foot switch, which bounces for milliseconds (Ganssle, A Guide to "
    "Debouncing, tested 18 switches); 30 ms is 3 readings at the 10 ms tick"
)
#: Why the control period is a multiple of the 10 ms tick and at most 100 ms.
_CONTROL_SOURCE = (
    "ours: the period an action is held, a whole number of 10 ms sensor ticks (the encoders, switches, stance and "
    "tumble counts keep the tick); 20-100 ms makes a seconds-long tumble tens of decisions (issue 17)"
)


@dataclasses.dataclass(frozen=True)
class SensorParams:
    """The sensor model's, the servos', the reward's parameters and the control period (constructor keywords of
    every beast id); the defaults are the -v0 ids', ideal servos and switches (:class:`RobotContactParams` has the
    robot's). ``control_timestep`` must also be a whole multiple of :data:`~polyenvs.beast.model.CONTROL_DT`."""

    backlash_deg: float = parameter(0.5, 0.0, 5.0, "deg", "ours: encoder dead band")
    tilt_threshold_deg: float = parameter(10.0, 0.0, 45.0, "deg", "ours: tilt-switch threshold below horizontal")
    ctrl_cost_weight: float = parameter(
        0.01, 0.0, 10.0, "", "weight of the control cost, mean squared torque / limit^2"
    )
    servo_deadband_deg: float = parameter(0.0, 0.0, 5.0, "deg", "v0: an ideal servo; " + _DEADBAND_SOURCE)
    switch_debounce_ms: float = parameter(0.0, 0.0, 200.0, "ms", "v0: ideal switches; " + _DEBOUNCE_SOURCE)
    control_timestep: float = parameter(CONTROL_DT, CONTROL_DT, 0.1, "s", _CONTROL_SOURCE)

    def __post_init__(self):
        check_parameters(self)
        if not math.isclose(self.ticks_per_step * CONTROL_DT, self.control_timestep, rel_tol=1e-9):
            raise ValueError(
                f"control_timestep must be a whole multiple of the {CONTROL_DT * 1000:g} ms tick, "
                f"got {show(self.control_timestep)}"
            )

    @property
    def ticks_per_step(self) -> int:
        """10 ms ticks per step: how long an action is held."""
        return round(self.control_timestep / CONTROL_DT)


@dataclasses.dataclass(frozen=True)
class RobotContactParams(SensorParams):
    """:class:`SensorParams` with the robot's contact model as defaults (the -v1 ids): the servo dead band and the
    foot-switch debounce that let the paper's gait roll under actuator noise, as the robot's hardware does."""

    servo_deadband_deg: float = parameter(0.25, 0.0, 5.0, "deg", _DEADBAND_SOURCE)
    switch_debounce_ms: float = parameter(30.0, 0.0, 200.0, "ms", _DEBOUNCE_SOURCE)


#: Model parameters settable through ``physics=`` (the rest are constructor keywords of their own).
PHYSICS_KEYS = tuple(
    f.name
    for f in M.BeastModelParams.__dataclass_fields__.values()
    if f.name not in ("polyhedron", "control", "locked_limbs")
)


def _check_physics(physics) -> dict:
    """``physics=``: None or a dict of :class:`polyenvs.beast.model.BeastModelParams` fields."""
    if physics is None:
        return {}
    if not isinstance(physics, dict):
        raise ValueError(f"physics must be a dict of model parameters, got {show(physics)}")
    unknown = sorted(set(physics) - set(PHYSICS_KEYS))
    if unknown:
        raise ValueError(f"physics has unknown parameter(s) {unknown}; expected some of {list(PHYSICS_KEYS)}")
    return physics


def _check_layouts(layouts, physics: dict) -> str:
    """``layouts``, checked; "train" and "test" draw the friction, body mass, kp and damping themselves, so
    ``physics`` may not set them beside it (refused rather than ignored)."""
    layouts = check_layouts(layouts)
    clash = sorted(set(physics) & set(LAYOUT_PARAMETERS))
    if layouts != "default" and clash:
        raise ValueError(
            f"layouts={layouts!r} draws {list(LAYOUT_PARAMETERS)} itself: physics may not set {clash} beside it "
            "(use layouts='default')"
        )
    return layouts


def _check_rendering(render_mode, modes, width, height) -> None:
    if render_mode is not None:
        check_choice("render_mode", render_mode, modes)
        if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
            # Headless: Gymnasium's renderer would try a GLFW window and fail; EGL renders off-screen.
            os.environ["MUJOCO_GL"] = "egl"
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or not 16 <= value <= 4096:
            raise ValueError(f"{name} must be an integer in [16, 4096], got {show(value)}")


class TumbleCounter:
    """Support changes that are tumbles, from the foot-contact bits.

    A support is a set of three or more feet on the floor, nothing else touching it, held for ``STANCE_TICKS`` ticks
    (contacts of the body or links make a fall, not a stance). A tumble is counted once
    the robot stands on a new support and its body has turned by more than 45 degrees since the last tumble (a
    tumble turns the 4-beast by 109.5 degrees and the 6-beast by 70.5; re-placing a foot without rolling turns it
    hardly at all). The turn is checked for as long as the new support holds, not only when it is reached: the
    6-beast lands its foot after about 30 degrees and turns the rest of the way standing on the new feet. Measuring
    from the last tumble, not the last support, counts a tumble that passes through a brief four-foot support once.

    The rules are the compiled :func:`polyenvs.beast.kernel.count_tumble`, which the tasks' step runs on its own
    copy of this state; this class holds one for a task written in Python.
    """

    def __init__(self, support: int, qpos: np.ndarray):
        self.state = np.zeros(KR.N_COUNTER)
        start_counter(self.state, support, qpos)

    @property
    def count(self) -> int:
        """Tumbles counted."""
        return int(self.state[KR.COUNT])

    def update(self, mask: int, n_feet: float, qpos: np.ndarray, other_contacts: float = 0.0) -> bool:
        """Feed one tick (the feet bitmask and count, MuJoCo's qpos, contacts of anything but a foot with the floor);
        True when a tumble has just completed. Only feet may touch the floor in a stance: a body lying on the floor
        with three feet down has fallen, not tumbled."""
        return KR.count_tumble(self.state, float(mask), float(n_feet), float(other_contacts), qpos)


def start_counter(counter: np.ndarray, support: int, qpos: np.ndarray) -> None:
    """A tumble counter's columns at an episode's start: standing on ``support`` (a feet bitmask, 0 while no feet are
    down) in the orientation of ``qpos``, no candidate, nothing counted."""
    counter[:] = 0.0
    counter[KR.SUPPORT], counter[KR.CANDIDATE] = support, -1.0
    counter[KR.QUAT : KR.QUAT + 4] = qpos[3:7]


def _reinitialize_egl_display() -> None:
    """Initialise MuJoCo's EGL display again if something else terminated it.

    MuJoCo initialises the process's EGL display once; SDL (a pygame window of another environment's
    ``render_mode="human"``, headless) terminates that same display when it quits, and every later MuJoCo context
    then fails with ``EGL_NOT_INITIALIZED``. ``eglInitialize`` on an initialised display changes nothing.
    """
    if os.environ.get("MUJOCO_GL") != "egl" or "mujoco.egl" not in sys.modules:
        return
    egl = sys.modules["mujoco.egl"]
    if egl.EGL_DISPLAY is not None:
        egl.EGL.eglInitialize(egl.EGL_DISPLAY, None, None)


class BeastEnv(MujocoEnv):
    """Base of the beast tasks (not registered itself); see the task classes for the documented environments."""

    metadata = {"render_modes": ["rgb_array", "depth_array"], "render_fps": round(1 / CONTROL_DT)}
    reward_names: tuple[str, ...] = ()
    metric_names: tuple[str, ...] = ()
    option_names: tuple[str, ...] = ("qpos", "qvel")
    #: Direction (rad, counter-clockwise from world +x) along which the summary measures velocity and distance.
    heading_rad: float = 0.0
    #: A task's constant command, appended to every observation as its ``command`` part (empty: none).
    command: tuple[float, ...] = ()
    #: How ``layouts=`` splits the physics (:data:`polyenvs.beast.layouts.LAYOUT_SPLIT`).
    layout_split = LAYOUT_SPLIT
    #: The sensing, servo, reward and control-period parameters the constructor takes as keywords (``**physical``)
    #: and their defaults: :class:`SensorParams`, or :class:`RobotContactParams` for the -v1 ids.
    params_class: type[SensorParams] = SensorParams
    #: The task's rules in the compiled step (:mod:`polyenvs.beast.kernel`: ``TUMBLE``, ``ROLL``, ``TURN``,
    #: ``RECOVER``) and which of their rewards (``OWN_REWARD`` or a -v1 id's); 0: a task written in Python, whose
    #: ``_task_step`` the step calls tick by tick (the adding guide's), which the native vector env does not run.
    task_kind: int = 0
    reward_kind: int = KR.OWN_REWARD
    #: Each task class's native vector env, ``TaskEnv.VectorEnv`` (:mod:`polyenvs.beast.vector`).
    VectorEnv = NativeVector(BeastVectorEnv)

    def __init__(  # noqa: PLR0913 - gym.make's keywords: all keyword-only, one per documented argument
        self,
        *,
        polyhedron: str = "tetrahedron",
        privileged: bool = False,
        disabled_limbs=(),
        control: str = "position",
        physics: dict | None = None,
        layouts: str = "default",
        render_mode: str | None = None,
        width: int = 480,
        height: int = 480,
        **physical,
    ):
        # Everything is checked before anything is built.
        check_choice("polyhedron", polyhedron, K.POLYHEDRA)
        self.privileged = check_bool("privileged", privileged)
        sensing = physical_parameters(type(self), self.params_class, physical)
        self.backlash_deg, self.tilt_threshold_deg = sensing.backlash_deg, sensing.tilt_threshold_deg
        self.ctrl_cost_weight = sensing.ctrl_cost_weight
        self.servo_deadband_deg, self.switch_debounce_ms = sensing.servo_deadband_deg, sensing.switch_debounce_ms
        self.control_timestep, self.ticks_per_step = sensing.control_timestep, sensing.ticks_per_step
        # One frame per step: MujocoEnv checks render_fps against dt.
        self.metadata = {**self.metadata, "render_fps": round(1 / self.control_timestep)}
        physics = _check_physics(physics)
        self.layouts = _check_layouts(layouts, physics)
        _check_rendering(render_mode, self.metadata["render_modes"], width, height)
        params = M.BeastModelParams(polyhedron=polyhedron, control=control, locked_limbs=disabled_limbs, **physics)
        frame_skip = round(CONTROL_DT / params.timestep)
        if not math.isclose(frame_skip * params.timestep, CONTROL_DT, rel_tol=1e-9):
            raise ValueError(f"timestep must divide the 10 ms control tick, got {params.timestep!r}")
        self.params = params
        self.polyhedron = polyhedron
        self.control = control
        self.disabled_limbs = params.locked_limbs
        self.n_limbs = params.n_limbs
        self.n_joints = 3 * params.n_limbs
        self.observation_structure = S.observation_layout(self.n_limbs, self.privileged, len(self.command))
        size = max(s.stop for s in self.observation_structure.values())
        limits = np.tile(params.joint_ranges, (params.n_limbs, 1))
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, f"beast_{polyhedron}.xml")
            with open(path, "w") as f:
                f.write(M.beast_xml(params))
            MujocoEnv.__init__(
                self,
                path,
                frame_skip,
                observation_space=self._observation_space(size, limits),
                render_mode=render_mode,
                width=width,
                height=height,
                camera_name="track",
            )
        self.fullpath = None  # generated, not a file
        self._init_buffers(size, limits)
        #: This episode's drawn physics (``layouts="train"`` or ``"test"``), written into the model at each reset.
        self._layout_values = {name: getattr(params, name) for name in LAYOUT_PARAMETERS}
        self._model_fields = ModelFields(self.model, self.control == "position") if self.layouts != "default" else None

    def _init_buffers(self, size: int, limits: np.ndarray) -> None:
        """The packed arrays the compiled step reads and writes (a batch of one: :class:`polyenvs.beast.kernel.Rows`)
        and the views of its row this env reads."""
        params, nj = self.params, self.n_joints
        rows = KR.allocate_rows(1, nj, size, len(self.metric_names))
        self._joints, self._misc, self._obs = rows.joints[0], rows.misc[0], rows.obs[0]
        self._joints[S.LIMIT_LOW], self._joints[S.LIMIT_HIGH] = limits[:, 0], limits[:, 1]
        if self.control == "position":
            self._joints[S.LOW], self._joints[S.SPAN] = limits[:, 0], limits[:, 1] - limits[:, 0]
            # A torque motor has no position servo, so no servo dead band.
            self._joints[S.DEADBAND] = math.radians(self.servo_deadband_deg)
        else:
            self._joints[S.LOW], self._joints[S.SPAN] = -params.torque_limit, 2 * params.torque_limit
        for limb in self.disabled_limbs:
            self._joints[S.FROZEN, 3 * (limb - 1) : 3 * limb] = 1.0
        if len(self.command):
            # Constant through the episode: written once, and the sensor kernel never touches it.
            self._obs[self.observation_structure["command"]] = self.command
        self._misc[: S.DEBOUNCE_TICKS + 1] = [
            math.radians(self.backlash_deg) / 2,
            1.0 / CONTROL_DT,
            math.sin(math.radians(self.tilt_threshold_deg)),
            float(self.privileged),
            1.0 / (params.torque_limit**2 * nj),
            round(self.switch_debounce_ms / 1000 / CONTROL_DT),
        ]
        self._write_task_constants(rows.task[0])
        self._reward_keys = tuple(f"reward_{name}" for name in self.reward_names)
        self._power_names = tuple(name for name in TRAVEL_METRICS if name in self.metric_names)
        self._travels = "cost_of_transport" in self._power_names
        self._unstable = False
        self._needs_reset = True
        self._use_rows(rows)

    @property
    def _elapsed(self) -> int:
        """10 ms ticks into the episode (the compiled step counts them in its task row)."""
        return int(self._task[KR.ELAPSED])

    @_elapsed.setter
    def _elapsed(self, ticks: int) -> None:
        self._task[KR.ELAPSED] = ticks

    def _join_rows(self, rows: KR.Rows, e: int) -> None:
        """Become row ``e`` of a vector env's batch: this env's state is copied there and its views point there."""
        for mine, batch in zip(self._rows, rows, strict=True):
            batch[e] = mine[0]
        self._use_rows(rows.row(e))

    def _write_task_constants(self, task: np.ndarray) -> None:
        """The compiled step's constants of this task: its rules, the physics ticks, the reward's weights and where
        each of its metrics is."""
        task[KR.KIND], task[KR.REWARD] = self.task_kind, self.reward_kind
        task[KR.FRAME_SKIP], task[KR.TICKS] = self.frame_skip, self.ticks_per_step
        task[KR.CTRL_WEIGHT] = self.ctrl_cost_weight
        for name, column in KR.TASK_CONSTANTS.items():
            task[column] = getattr(self, name, 0.0)
        for name, column in KR.METRIC_COLUMNS.items():
            task[column] = self.metric_names.index(name) if name in self.metric_names else -1

    def _use_rows(self, rows: KR.Rows) -> None:
        """Run on ``rows`` (a batch of one: this env's own, or a row of a vector env's batch, whose arrays then hold
        this env's state) and point the views and the MuJoCo addresses at them."""
        self._rows = rows
        self._joints, self._misc, self._obs = rows.joints[0], rows.misc[0], rows.obs[0]
        self._task, self._metric_row, self._out = rows.task[0], rows.metrics[0], rows.out[0]
        self._bind()
        # The step's action, as float64 (exactly the float32 or float64 given), so that one machine-code version
        # of the compiled step serves every call, called without numba's per-call type dispatch.
        self._action = np.zeros((1, self.n_joints))
        self._compiled_step = compiled_for(KR.step_rows, self._active, self._action, *rows)

    # --- set-up helpers ---------------------------------------------------------------------------------------
    def _observation_space(self, size: int, limits: np.ndarray) -> spaces.Box:
        """Bounds of every part; the encoder angles' are the joint limits, so a policy can read them from here."""
        low, high = np.empty(size, np.float32), np.empty(size, np.float32)
        bounds = {
            "joint_vel": S.VELOCITY_CLIP,
            "tilt": 1.0,
            "foot_contact": 1.0,
            "prev_action": 1.0,
            "body_pos": np.inf,
            "body_quat": 1.0,
            "body_linvel": S.VELOCITY_CLIP,
            "body_angvel": S.VELOCITY_CLIP,
            "command": 1.0,
        }
        for name, part in self.observation_structure.items():
            if name == "joint_pos":
                low[part], high[part] = limits[:, 0], limits[:, 1]
            else:
                high[part] = bounds[name]
                low[part] = 0.0 if name in ("tilt", "foot_contact") else -bounds[name]
        return spaces.Box(low, high, dtype=np.float32)

    def _set_action_space(self):
        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.model.nu,), dtype=np.float32)
        return self.action_space

    def _bind(self) -> None:
        """Views into MjData used every step and the addresses the compiled step reaches them by (rebuilt after
        unpickling: a pickled view would be a copy, and the structs are at new addresses)."""
        d, m = self.data, self.model
        self._qpos, self._qvel, self._ctrl = d.qpos, d.qvel, d.ctrl
        self._sensordata, self._force, self._warnings = d.sensordata, d.actuator_force, d.warning.number
        self._shape = (self.n_joints,)
        if (m.nq, m.nv, m.nu, m.nsensordata) != (7 + self.n_joints, 6 + self.n_joints, self.n_joints, self.n_limbs + 4):
            raise ValueError(f"the model's sizes do not match the compiled step's for {self.n_limbs} limbs")
        arrays = (d.qpos, d.qvel, d.ctrl, d.sensordata, d.actuator_force, d.warning.number)
        self._rows.handles[0] = [m._address, d._address, *(a.ctypes.data for a in arrays)]
        self._active = np.ones(1, dtype=bool)

    def render(self):
        if self._needs_reset:
            raise ResetNeeded("call reset() before render()")
        _reinitialize_egl_display()
        return super().render()

    #: Views (of MjData, of the rows) rebuilt after unpickling: pickled, each would be a copy of its own.
    _VIEWS = ("_qpos", "_qvel", "_ctrl", "_sensordata", "_force", "_warnings", "_joints", "_misc", "_obs", "_task")
    _VIEWS += ("_metric_row", "_out", "_compiled_step")

    def __getstate__(self):
        state = self.__dict__.copy()
        for name in self._VIEWS:
            del state[name]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._use_rows(self._rows)

    # --- Gymnasium API ------------------------------------------------------------------------------------------
    @property
    def dt(self) -> float:
        return self.control_timestep

    def action_to_control(self, action) -> np.ndarray:
        """The actuator controls an action in [-1, 1] asks for: joint targets (rad) or torques (N m)."""
        return self._joints[S.LOW] + (np.asarray(action, dtype=np.float64) + 1) / 2 * self._joints[S.SPAN]

    def control_to_action(self, control) -> np.ndarray:
        """The action (float32, clipped to [-1, 1]) that asks for these controls: joint targets or torques."""
        action = 2 * (np.asarray(control, dtype=np.float64) - self._joints[S.LOW]) / self._joints[S.SPAN] - 1
        return np.clip(action, -1, 1).astype(np.float32)

    def step(self, action):
        if self._needs_reset:
            raise ResetNeeded("call reset() before step()")
        # Float arrays are checked by the compiled step as they are (float32 widens exactly); anything else is
        # converted first.
        a = action if type(action) is np.ndarray and action.dtype in _FLOATS else real_array("action", action)
        if a.shape != self._shape:
            raise ValueError(f"action must have shape {self._shape}, got {show(action)}")
        if not self.task_kind:
            return self._python_step(a)
        self._action[0] = a
        bad = self._compiled_step(self._active, self._action, *self._rows)
        if bad:
            raise ValueError(f"action[{bad - 1}] = {show(a[bad - 1])} is outside [-1, 1]")
        out = self._out.tolist()  # the terms first (zip stops at the task's), then the sum, terminated, diverged
        if out[KR.DIVERGED]:
            return self._diverged_result()
        info = dict(zip(self._reward_keys, out, strict=False))
        info["sim_unstable"] = False
        if out[KR.TERMINATED]:
            info["episode_metrics"] = self.episode_metrics()
            return self._obs.copy(), out[KR.REWARD_SUM], True, False, info
        return self._obs.copy(), out[KR.REWARD_SUM], False, False, info

    def _diverged_result(self):
        """A diverged step: truncated, the last finite observation, a zero reward and zero terms."""
        info = dict.fromkeys(self._reward_keys, 0.0)
        info["sim_unstable"] = True
        info["episode_metrics"] = self.episode_metrics()
        return self._obs.copy(), 0.0, False, True, info

    def _python_step(self, action: np.ndarray):
        """The step of a task whose rules are Python (``_task_step``), tick by tick."""
        bad = S.actuate(action, self._joints, self._ctrl)
        if bad:
            raise ValueError(f"action[{bad - 1}] = {show(action[bad - 1])} is outside [-1, 1]")
        # The controls are written once: actuating again with the same action writes the same ones (the dead band
        # keeps a target already within it), so the action is held exactly as a 10 ms agent repeating it holds it.
        terms, terminated = self._tick()
        for _ in range(self.ticks_per_step - 1):
            if terms is None or terminated:
                break
            more, terminated = self._tick()
            terms = None if more is None else tuple(t + m for t, m in zip(terms, more, strict=True))
        if terms is None:
            return self._diverged_result()
        info = dict(zip(self._reward_keys, terms, strict=True))
        info["sim_unstable"] = False
        if terminated:
            info["episode_metrics"] = self.episode_metrics()
        return self._obs.copy(), sum(terms), terminated, False, info

    def episode_metrics(self) -> dict[str, float]:
        """The episode's metrics so far (``metric_names``): after its end, the final ones, until the next reset."""
        if self._needs_reset:
            raise ResetNeeded("call reset() before episode_metrics()")
        if self.task_kind:
            return dict(zip(self.metric_names, self._metric_row.tolist(), strict=True))
        return dict(self._metrics)

    def _tick(self) -> tuple[tuple[float, ...] | None, bool]:
        """One 10 ms tick of a Python task under the controls written: (the task's reward terms, terminated), or
        (None, False) once the simulation has diverged (a zero reward for the whole step, however many ticks went
        well before)."""
        mujoco.mj_step(self.model, self.data, nstep=self.frame_skip)
        self._elapsed += 1
        if self._unstable or S.sense(
            (self._qpos, self._qvel, self._sensordata, self._force, self._warnings), S.TILT_AXES, self._joints,
            self._misc, self._obs,
        ):  # fmt: skip
            self._unstable = True
            return None, False
        summary = S.StepSummary(*self._misc[S.SUMMARY].tolist())
        result = self._task_step(summary)
        if self._power_names:
            self._record_power(summary.power)
        return result

    def _start_power(self) -> None:
        """The power metrics' start, after the task's (the layout has set this episode's masses)."""
        self._power_sum = 0.0  # W, summed over the ticks
        gravity = float(np.linalg.norm(self.model.opt.gravity))
        self._weight_n = mujoco.mj_getTotalmass(self.model) * gravity
        self._metrics.update(dict.fromkeys(self._power_names, 0.0))

    def _record_power(self, power: float) -> None:
        """A tick's mechanical power (W) into the power metrics, after the task's step has written its distance."""
        self._power_sum += power
        m = self._metrics
        m["mean_power_w"] = self._power_sum / self._elapsed
        if power > m["peak_power_w"]:
            m["peak_power_w"] = power
        if self._travels:
            distance = m["distance_m"]
            energy_j = self._power_sum * CONTROL_DT
            m["cost_of_transport"] = energy_j / (self._weight_n * distance) if distance > 0.0 else 0.0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        options = self._check_options(options)
        gym.Env.reset(self, seed=seed)
        rng = self.np_random
        if self._model_fields is not None:  # the layout's physics first, then the start state, from one generator
            self._layout_values = draw_layout(rng, self.layouts)
            self._model_fields.apply(self.data, self._layout_values)
        if "qpos" in options:
            qpos = options["qpos"]
            qvel = options.get("qvel", np.zeros(self.model.nv))
        else:
            qpos, qvel = (np.round(q, START_DECIMALS) for q in self._initial_state(rng))
        d, m = self.data, self.model
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        joints, js = d.qpos[7:], self._joints
        js[S.HOLD] = joints if self.control == "position" else 0.0
        for k, limb in enumerate(self.disabled_limbs):
            m.eq_data[3 * k : 3 * k + 3, 0] = joints[3 * (limb - 1) : 3 * limb]
        d.ctrl[:] = js[S.HOLD]
        # The previous action is the one that holds the start pose (what a servo was last told).
        js[S.APPLIED] = self.control_to_action(js[S.HOLD])
        mujoco.mj_forward(m, d)
        half = self._misc[S.HALF_BAND]
        js[S.MOTOR] = joints + rng.uniform(-half, half, self.n_joints)
        js[S.READING] = js[S.MOTOR]
        js[S.SWITCH] = -1.0  # the switches start settled: the first reading is reported as it is
        self._unstable = False
        self._elapsed = 0
        self._needs_reset = False
        x, y = d.qpos[0], d.qpos[1]
        self._misc[S.PREV_X : S.HEAD_Y + 1] = [x, y, x, y, math.cos(self.heading_rad), math.sin(self.heading_rad)]
        S.sense(
            (self._qpos, self._qvel, self._sensordata, self._force, self._warnings), S.TILT_AXES, self._joints,
            self._misc, self._obs,
        )  # fmt: skip
        self._start_task(int(self._misc[S.FEET_MASK]))
        info = dict.fromkeys(self._reward_keys, 0.0)
        info["sim_unstable"] = False
        return self._obs.copy(), info

    def _start_task(self, feet_mask: int) -> None:
        """The task's state and metrics at the episode's start, once the start state is sensed."""
        if not self.task_kind:
            self._task_reset(feet_mask)
            self._start_power()
            return
        task = self._task
        task[KR.ELAPSED :] = 0.0
        start_counter(task[KR.COUNTER : KR.COUNTER + KR.N_COUNTER], feet_mask, self._qpos)
        # The power metrics' weight: the layout has set this episode's masses.
        task[KR.WEIGHT_N] = mujoco.mj_getTotalmass(self.model) * float(np.linalg.norm(self.model.opt.gravity))
        self._metric_row[:] = 0.0
        self._task_reset(feet_mask)

    def _check_options(self, options) -> dict:
        checked = dict(check_options(options, self.option_names))
        for name, size in (("qpos", self.model.nq), ("qvel", self.model.nv)):
            if name in checked:
                value = real_array(f"option {name}", checked[name])
                if value.shape != (size,) or not np.isfinite(value).all():
                    raise ValueError(f"option {name} must be {size} finite numbers, got {show(checked[name])}")
                checked[name] = value.copy()
        if "qvel" in checked and "qpos" not in checked:
            raise ValueError("option qvel needs qpos too")
        if "qpos" in checked:
            quat = checked["qpos"][3:7]
            if not 0.5 < np.linalg.norm(quat) < 2:
                raise ValueError(f"option qpos must hold a unit quaternion at 3:7, got {show(quat)}")
            checked["qpos"][3:7] = quat / np.linalg.norm(quat)
        return checked

    def episode_layout(self) -> dict[str, float]:
        """This episode's physics as :attr:`layout_split` classifies it: friction, body_mass, kp, damping."""
        return dict(self._layout_values)

    # --- shared task helpers -----------------------------------------------------------------------------------
    def _stance_state(self, rng: np.random.Generator, position_noise=0.005, yaw_noise_deg=2.0, free_noise_deg=2.0):
        """The start stance, turned by a small random yaw and shifted a few mm; free limbs jittered a little."""
        radius, height = M.START_STANCE[self.polyhedron]
        yaw = math.radians(yaw_noise_deg) * rng.uniform(-1, 1)
        qpos = M.stance_qpos(self.params, radius, height, yaw)
        qpos[:2] += position_noise * rng.uniform(-1, 1, 2)
        _, stance = M.stance_orientation(self.polyhedron)
        free = np.ones(self.n_limbs, dtype=bool)
        free[stance] = False
        jitter = math.radians(free_noise_deg) * rng.uniform(-1, 1, (self.n_limbs, 3))
        qpos[7:] += (jitter * free[:, None]).ravel()
        return qpos, np.zeros(self.model.nv)

    # --- what a task provides -------------------------------------------------------------------------------------
    def _initial_state(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        return self._stance_state(rng)

    def _task_reset(self, feet_mask: int) -> None:
        """Set up the episode's bookkeeping (``self._metrics``) once the start state is sensed."""
        raise NotImplementedError

    def _task_step(self, summary: S.StepSummary) -> tuple[tuple[float, ...], bool]:
        """(reward terms in ``reward_names`` order, terminated) from the tick's summary."""
        raise NotImplementedError
