"""The Gymnasium surface shared by the Buckybot tasks: spaces, seeding, reset options, sensing, info, rendering.

Everything inside works on a batch of robots ("rows"), like the simulator: a Gymnasium ``BuckybotEnv`` is a batch
of one, and :class:`polyenvs.buckybot.vector.BuckybotVectorEnv` runs the same class with many rows, so the task
equations exist once. A task subclasses :class:`BuckybotEnv` and fills in the batched hooks (``_task_reset``,
``_task_step``, ``_task_observation``, ``_task_terminated``) and ``_episode_metrics(row)``; the physics lives in
:mod:`polyenvs.buckybot.simulator`, the sensors in :mod:`polyenvs.buckybot.sensors`.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.floor_plans import make_floor_plan, random_room
from polyenvs.buckybot.simulator import BuckybotSimulator, TipModel
from polyenvs.core.floor_plan import FloorPlan
from polyenvs.core.jit import njit
from polyenvs.core.validation import check_action, check_in_range, check_positive

__all__ = ["BuckybotEnv", "SENSOR_OBSERVATION_STRUCTURE"]

#: Layout of the sensor part of every Buckybot observation: name -> (start, stop) indices.
SENSOR_OBSERVATION_STRUCTURE = {
    "range": (0, 6),  # reading / 182.88 cm for valid readings; 0 when too close, 1 when no return
    "too_close": (6, 12),  # 1 where the sensor did not settle (< 30.48 cm)
    "no_return": (12, 18),  # 1 where nothing was seen within 182.88 cm
    "tip_failed": (18, 19),  # 1 if the last tip was blocked (the accelerometer reports the same face)
}
_N_SENSOR_OBS = 19
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


class BuckybotEnv(gym.Env):
    """Base class of the Buckybot lattice environments (see the task classes for the full documentation)."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 4}
    #: Extra observation entries appended by a task: name -> size.
    task_observation_sizes: dict[str, int] = {}
    #: Bounds of the task's extra observation entries, in order.
    task_observation_low: tuple[float, ...] = ()
    task_observation_high: tuple[float, ...] = ()
    #: Names of the reward terms, in the order of the task's reward columns.
    reward_names: tuple[str, ...] = ()
    #: Rows (robots) this instance simulates; a vector env builds the class with more (see ``vector.py``).
    _batch_size = 1

    def __init__(
        self,
        *,
        floor_plan="rectangle",
        noise_scale: float = 1.0,
        range_noise_scale: float = 1.0,
        step_forward_cm: float = 9.266,
        step_forward_sd_cm: float = 0.105,
        step_lateral_cm: float = -0.745,
        step_lateral_sd_cm: float = 0.149,
        heading_change_deg: float = 0.31,
        heading_sd_deg: float = 0.44,
        body_radius_cm: float = geo.BODY_RADIUS_CM,
        render_mode: str | None = None,
    ):
        self.noise_scale = check_in_range("noise_scale", noise_scale, 0.0, 1.0)
        self.range_noise_scale = check_positive("range_noise_scale", range_noise_scale, allow_zero=True)
        self.body_radius_cm = check_positive("body_radius_cm", body_radius_cm)
        if self.body_radius_cm >= 2 * geo.STEP_LENGTH_CM + 40:
            raise ValueError(f"body_radius_cm={body_radius_cm} is too large for the lattice robot")
        model = TipModel(
            forward_mean_cm=check_positive("step_forward_cm", step_forward_cm),
            forward_sd_cm=check_positive("step_forward_sd_cm", step_forward_sd_cm, allow_zero=True),
            lateral_mean_cm=check_in_range("step_lateral_cm", step_lateral_cm, -5.0, 5.0),
            lateral_sd_cm=check_positive("step_lateral_sd_cm", step_lateral_sd_cm, allow_zero=True),
            heading_mean_deg=check_in_range("heading_change_deg", heading_change_deg, -30.0, 30.0),
            heading_sd_deg=check_positive("heading_sd_deg", heading_sd_deg, allow_zero=True),
        )
        self.tip_model = model.scaled(self.noise_scale)
        # A start this far from every wall leaves all three tips free: each lands one step away, the body needs
        # its radius.
        self.start_clearance_cm = self.body_radius_cm + geo.STEP_LENGTH_CM + 1.0
        self.floor_plan = make_floor_plan(floor_plan)  # None: a random room at every reset
        if self.floor_plan is not None:
            self._check_plan(self.floor_plan, "floor_plan")
        elif self._batch_size > 1:
            raise ValueError("floor_plan='random' draws a room per episode; a vector env needs one fixed plan")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode

        n = self._batch_size
        self.sim = BuckybotSimulator(n, self.tip_model, self.range_noise_scale, self.body_radius_cm)
        self.action_space = spaces.Discrete(3)
        low = np.concatenate([np.zeros(_N_SENSOR_OBS), self.task_observation_low]).astype(np.float32)
        high = np.concatenate([np.ones(_N_SENSOR_OBS), self.task_observation_high]).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_structure = dict(SENSOR_OBSERVATION_STRUCTURE)
        start = _N_SENSOR_OBS
        for name, size in self.task_observation_sizes.items():
            self.observation_structure[name] = (start, start + size)
            start += size

        self.plan: FloorPlan | None = None
        self._observations = np.zeros((n, *self.observation_space.shape), dtype=np.float32)
        self._rewards = np.zeros((n, len(self.reward_names)))
        self._reward_keys = [f"reward_{name}" for name in self.reward_names]
        self._actions = np.zeros(n, dtype=np.int64)
        self._active = np.zeros(n, dtype=bool)
        self._row0 = np.zeros(1, dtype=np.int64)
        # Per-row episode records.
        self.steps = np.zeros(n, dtype=np.int64)
        self.blocked_tips = np.zeros(n, dtype=np.int64)
        self.oscillation_events = np.zeros(n, dtype=np.int64)
        self.last_blocked = np.zeros(n, dtype=bool)
        self._last_tip_moved = np.zeros(n, dtype=bool)
        self.true_path: list[list[float]] = []  # row 0's (x, y) after every step, for rendering
        self.dead_reckoned_path: list[list[float]] = []
        self._renderer = None

    # --- helpers ----------------------------------------------------------------------------------------------
    def _check_plan(self, plan: FloorPlan, name: str) -> None:
        if not plan.has_room(self.start_clearance_cm):
            raise ValueError(f"{name} leaves no room for the robot ({self.start_clearance_cm:.1f} cm from every wall)")

    @property
    def position(self) -> np.ndarray:
        """Row 0's true position (cm)."""
        return self.sim.position[0]

    # Row 0's last readings: views of the simulator's buffers, never handed out as observations.
    @property
    def last_reading(self) -> np.ndarray:
        return self.sim.reading[0]

    @property
    def last_too_close(self) -> np.ndarray:
        return self.sim.too_close[0]

    @property
    def last_no_return(self) -> np.ndarray:
        return self.sim.no_return[0]

    # --- Gymnasium API ----------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._reset_rows(self._row0, dict(options or {}))
        self.true_path = [self.sim.position[0].tolist()]
        self.dead_reckoned_path = [self.sim.dr_position[0].tolist()]
        return self._get_observations()[0].copy(), self._get_info(0)

    def step(self, action):
        if self.plan is None:
            raise gym.error.ResetNeeded("call reset() before step()")
        if type(action) in _INT_TYPES and 0 <= action < 3:
            a = int(action)  # the common case, checked without the space's slower generic test
        else:
            check_action(self.action_space, action)
            a = int(action)
        self._actions[0] = a
        self._advance(self._actions, self.np_random.standard_normal((1, 9)))  # 3 for the tip, 6 for the sensors
        self.true_path.append(self.sim.position[0].tolist())
        self.dead_reckoned_path.append(self.sim.dr_position[0].tolist())
        reward = float(sum(self._rewards[0].tolist()))
        terminated = bool(self._terminated[0])
        if self.render_mode == "human":
            self.render()
        return self._get_observations()[0].copy(), reward, terminated, False, self._get_info(0)

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from polyenvs.buckybot.rendering import BuckybotRenderer

        if self._renderer is None:
            self._renderer = BuckybotRenderer(self.render_mode, self.metadata["render_fps"])
        return self._renderer.render(self)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def action_masks(self) -> np.ndarray:
        """Tips that would not hit a wall (true geometry), for sb3-contrib's MaskablePPO."""
        return self.sim.tip_allowed[0].copy()

    # --- the batched core (shared with the vector env) --------------------------------------------------------
    def _reset_rows(self, rows: np.ndarray, options: dict) -> None:
        """Start new episodes in ``rows``: place the robots, sense once, set up the task."""
        allowed = {"pose", "face", *self._task_option_names()}
        if set(options) - allowed:
            raise ValueError(
                f"unknown reset option(s) {sorted(set(options) - allowed)}; expected some of {sorted(allowed)}"
            )
        if self.floor_plan is None or self.plan is None:
            self.plan = self.floor_plan if self.floor_plan is not None else self._random_plan()
            self.sim.set_walls(self.plan.table)
        rng = self.np_random
        k = len(rows)
        if "pose" in options:
            positions, headings = self._option_pose(options)
        else:
            positions = self.plan.sample_start(rng, self.start_clearance_cm, size=k)
            headings = rng.uniform(0.0, 2 * np.pi, size=k)
        faces = self._option_face(options) if "face" in options else rng.integers(geo.N_FACES, size=k)
        self.sim.place(rows, positions, faces, headings)
        for record in (self.steps, self.blocked_tips, self.oscillation_events):
            record[rows] = 0
        self.last_blocked[rows] = False
        self._last_tip_moved[rows] = False
        self.sim.sense(rng.standard_normal((len(rows), 6)), rows)
        self._task_reset(rows, options)
        self._rewards[rows] = 0.0
        self._terminated = self._task_terminated()

    def _option_pose(self, options: dict) -> tuple[np.ndarray, float]:
        try:
            x, y, heading_deg = (float(v) for v in options["pose"])
        except (TypeError, ValueError):
            raise ValueError("reset option 'pose' must be (x_cm, y_cm, heading_deg)") from None
        position = np.array([x, y])
        if not np.isfinite(position).all() or not np.isfinite(heading_deg):
            raise ValueError(f"reset option 'pose' must be finite, got {options['pose']!r}")
        clearance = float(self.plan.clearance(position))
        if clearance < self.body_radius_cm:
            raise ValueError(
                f"reset option 'pose' puts the robot {clearance:.1f} cm from a wall "
                f"(inside or touching it; the body radius is {self.body_radius_cm} cm)"
            )
        if not self.plan.in_main_region(position):
            raise ValueError(f"reset option 'pose' {options['pose']!r} is outside the plan's free space")
        return position, np.radians(heading_deg)

    @staticmethod
    def _option_face(options: dict) -> int:
        face = options["face"]
        if isinstance(face, bool) or not isinstance(face, (int, np.integer)) or not 1 <= face <= geo.N_FACES:
            raise ValueError(f"reset option 'face' must be an integer 1..20, got {face!r}")
        return int(face) - 1

    def _advance(self, actions: np.ndarray, normals: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Tip and sense every row whose action is >= 0 (``rows``, if given, lists them), then score the step.

        Rows with action -1 were just reset by a vector env: they neither move nor score this step.
        """
        blocked = self.sim.step(actions, normals, rows)
        active = self._active
        _update_records(
            actions, blocked, active, self.steps, self.blocked_tips, self.oscillation_events, self._last_tip_moved,
            self.last_blocked,
        )  # fmt: skip
        self._task_step(actions, blocked, active)
        self._terminated = self._task_terminated()

    def _get_observations(self) -> np.ndarray:
        """(rows, D) observations, in a buffer the caller must copy before handing out."""
        obs, sim = self._observations, self.sim
        obs[:, 0:6] = sim.normalised
        obs[:, 6:12] = sim.too_close
        obs[:, 12:18] = sim.no_return
        obs[:, 18] = self.last_blocked
        if obs.shape[1] > _N_SENSOR_OBS:
            obs[:, _N_SENSOR_OBS:] = self._task_observation()
        return obs

    def _get_info(self, row: int) -> dict[str, Any]:
        sim = self.sim
        heading_deg = math.degrees(sim.heading[row])
        face, edge0 = int(sim.face[row]), int(sim.edge0[row])
        info = {
            "action_mask": sim.tip_allowed[row].astype(np.int8),
            "face": face + 1,
            "heading_deg": heading_deg,
            "tip_directions_deg": np.array([heading_deg, (heading_deg + 120.0) % 360.0, (heading_deg + 240.0) % 360.0]),
            "actuators": _ACTUATOR_NAMES[face][edge0],
            "sensor_faces": _SENSOR_FACES[face][edge0],
            "pose": np.array([*sim.position[row].tolist(), heading_deg]),
            "dead_reckoned_pose": np.array([*sim.dr_position[row].tolist(), math.degrees(sim.dr_heading[row])]),
            "true_range_cm": sim.true_range[row].copy(),
            "wall_distance_cm": float(sim.wall_distance[row]),
            "blocked": bool(self.last_blocked[row]),
        }
        for key, value in zip(self._reward_keys, self._rewards[row].tolist(), strict=True):
            info[key] = value
        info["episode_metrics"] = self._episode_metrics(row)
        return info

    def _random_plan(self) -> FloorPlan:
        for _ in range(100):
            plan = random_room(self.np_random)
            if plan.has_room(self.start_clearance_cm):
                return plan
        raise RuntimeError("the random room generator failed to make a usable room")  # pragma: no cover

    def _task_option_names(self) -> tuple[str, ...]:
        return ()

    # --- task hooks (batched over rows) -----------------------------------------------------------------------
    def _task_reset(self, rows: np.ndarray, options: dict) -> None:
        """Set up the task in ``rows`` after the robots are placed and have sensed once."""

    def _task_step(self, actions: np.ndarray, blocked: np.ndarray, active: np.ndarray) -> None:
        """Write this step's reward terms into ``self._rewards`` (rows x reward_names); 0 where not active."""
        raise NotImplementedError

    def _task_observation(self) -> np.ndarray:
        """(rows, task observation size) entries appended to the sensor observation."""
        return np.zeros((self._batch_size, 0))

    def _task_terminated(self) -> np.ndarray:
        return np.zeros(self._batch_size, dtype=bool)

    def _episode_metrics(self, row: int) -> dict[str, float]:
        """Row ``row``'s task metrics so far (at an episode's last step: that episode's)."""
        return {"blocked_tips": int(self.blocked_tips[row]), "oscillation_events": int(self.oscillation_events[row])}


@njit(cache=True)
def _update_records(actions, blocked, active, steps, blocked_tips, oscillation_events, last_tip_moved, last_blocked):
    for b in range(actions.shape[0]):
        active[b] = actions[b] >= 0
        if not active[b]:
            continue
        steps[b] += 1
        if blocked[b]:
            blocked_tips[b] += 1
        elif actions[b] == 0 and last_tip_moved[b]:
            oscillation_events[b] += 1  # undid the previous tip: the robot alternates between two faces
        last_tip_moved[b] = not blocked[b]
        last_blocked[b] = blocked[b]
