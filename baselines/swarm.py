"""The paper's AP-lite controller and the physicomimetics formation controller, acting on one robot's observation.

Every ``predict`` works on a batch of robots (first axis) with numpy over rows: a swarm's robots share the policy
(parameter sharing), and 256 robots cost a handful of array operations, not 256 calls.

AP-lite (Hettiarachchi and Spears, ``seeds/004``, appendix), the reading implemented here
(``spec/geometry-checks.md`` part C lists the ambiguities):

1. ``dcl`` / ``dcr`` are the left / right powers; the cap test reads ``power right > MAX_SPEED or power left >
   MAX_SPEED``; only non-negative powers are applied (a negative one gives 0: the robot never reverses).
2. Loop scoping: the forces of all sensors are accumulated first, then ONE velocity and power update per cycle
   (read literally the update would run once per sensor, and the robot would not slow before a wall).
3. ``theta_new <= PI/2.5`` is a typo for ``PI/2``: the velocity must point into quadrants I or IV.
4. When ``theta_new`` is out of range no powers are assigned: the robot halts (0, 0), as the text says.
5. ``atan2`` returning exactly -pi is treated as pi (w = 0), not as a hard turn.
6. ``delta`` is the direction of the velocity change (the force); ``w`` in radians is used directly as the
   fractional differential ``v (1 +- alpha w)``.
7. ``v`` is persistent (the policy's state, one value per robot) and starts at 70; it converges geometrically.
8. ``FR = 0.5`` is a speed retention; ``vy`` is reset to 0 every cycle.
9. The integer casts truncate, as in C, including the proportional cap's integer division.
10. The filter ``reading > 30`` compares raw A/D values (a noise floor: raw 30 is 247 cm); the 30-inch reactive
    range is ``r = RANGE - inches`` clamped at 0 (raw 87.6).
11. S0 is right-most, S1 and S2 the middle, S3 left-most; the virtual angles are -60°, -15°, +15°, +60° (*ours*).
12. X80Pro readings (0..80, 80 = nothing) are converted back to the Maxelbot's raw values by the paper's function;
    on the X80Pro the paper reads only the two outer-most sensors.

The paper's goal force is (100, 0) in the robot's frame: it always points along the heading, so a robot that has
turned away from the goal never turns back (:class:`APLite`). :class:`APLiteGoalSeeking` points it at the sensed
light instead. The halt rule's trap (an obstacle ahead on both middle sensors stops the robot for good) is part
of the algorithm and is not patched: ``last_stopped`` shows, per robot, where the last call halted it.

In the X80Pro's corridor the faithful AP-lite turns as the paper's Figures 8-10 report: left at the first obstacle
on the right, right at the last obstacle on the left before the light. Unlike the paper's robot, which misses the
obstacles in between, ours also turns from L1 and R2 and weaves between the walls on the way
(``tests/test_papers_claims_swarm.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from baselines.base import Policy
from polyenvs.core import libm
from polyenvs.core.parameters import check_parameters, parameter, physical_parameters
from polyenvs.core.validation import check_in_range
from polyenvs.swarm.env import structure_for
from polyenvs.swarm.formation_v0 import OBSERVATION_PARTS as FORMATION_PARTS
from polyenvs.swarm.platforms import SENSOR_ANGLES_DEG, get_platform
from polyenvs.swarm.sensors import inches_from_raw, raw_from_observation

__all__ = ["APLite", "APLiteGoalSeeking", "FormationController", "observation_layout"]

#: The observation parts a task may add to the family's, which these controllers read around: none (corridor,
#: obstacle field) or the formation's leader (``formation_v0``). The length of an observation tells them apart.
TASK_PARTS = ({}, FORMATION_PARTS)

#: The appendix's constants that stay fixed (its force law's are :class:`APLiteTunables`): the power cap, the time step
#: and mass (which only scale the force law's gains), the noise floor and the starting speed.
MAX_SPEED = 70
STEP = 1.0
MASS = 1.0
READING_FILTER = 30.0
INITIAL_VELOCITY = 70.0


@dataclasses.dataclass(frozen=True)
class APLiteTunables:
    """AP-lite's force law, the appendix's values (what ``polyenvs tune`` searches, and what an :class:`APLite`
    accepts): the reactive range, the gains of the middle and side sensors, the goal force, the speed retention
    (friction) and the turn gain."""

    range_in: float = parameter(30.0, 5.0, 60.0, "in", "paper: 30 inches")
    k_mid: float = parameter(5.0, 0.0, 20.0, "", "paper appendix")
    k_side: float = parameter(4.0, 0.0, 20.0, "", "paper appendix")
    goal_force: float = parameter(100.0, 10.0, 300.0, "", "paper appendix: Fx = 100")
    friction: float = parameter(0.5, 0.0, 0.95, "", "paper appendix: FR = 0.5")
    alpha: float = parameter(1.0, 0.1, 3.0, "", "paper appendix")

    def __post_init__(self):
        check_parameters(self)


@dataclasses.dataclass(frozen=True)
class FormationTunables(APLiteTunables):
    """The formation controller's: AP-lite's force law and the springs' stiffness."""

    spring_k: float = parameter(300.0, 50.0, 1000.0, "1/m", "the feasibility study: 200-400 holds a hexagon")


def observation_layout(dim: int) -> dict[str, tuple[int, int]]:
    """The observation structure of a swarm robot's ``dim``-long observation, with the task parts of
    :data:`TASK_PARTS` that fit it (``ValueError`` if none does)."""
    for parts in TASK_PARTS:
        try:
            return structure_for(dim, parts)
        except ValueError:
            continue
    raise ValueError(f"an observation of length {dim} is not a swarm robot's")


class APLite(Policy):
    """AP-lite, the paper's appendix (the reading in the module docstring), with the heading-fixed goal force.

    Args:
        platform: the robot (:data:`polyenvs.swarm.platforms.PLATFORMS`), which the observation space cannot tell:
            its IR scale reads the observation's ``ir`` part, and its ``controller_sensors`` are the sensors the
            paper's AP-lite reads on it (all four on the Maxelbot, the two outer-most on the X80Pro).
        sensors: read these sensors instead of the platform's (indices 0..3).
        sensor_angles_deg: the virtual sensor angles S0..S3.
        range_in, k_mid, k_side, goal_force, friction, alpha: the force law (:class:`APLiteTunables`, whose
            ranges they must be in).

    Attributes:
        last_stopped: per robot of the last batch, whether AP-lite commanded (0, 0).
        last_turn: per robot, the turn ``w`` (rad) of the last call (the paper's Figure 10).
    """

    memory_size = 1
    tunables: type[APLiteTunables] = APLiteTunables

    def __init__(self, observation_space, action_space, *, platform: str = "maxelbot", sensors=None,
                 sensor_angles_deg=SENSOR_ANGLES_DEG, **force_law):  # fmt: skip
        super().__init__(observation_space, action_space)
        self.law = physical_parameters(type(self), APLiteTunables, force_law)
        robot = get_platform(platform)
        self.ir_scale = robot.ir_scale
        if sensors is None:
            sensors = robot.controller_sensors
        self.sensors = tuple(int(s) for s in sensors)
        if not self.sensors or any(s not in range(4) for s in self.sensors):
            raise ValueError(f"sensors must be indices 0..3, got {sensors!r}")
        self.sensor_angles_deg = tuple(check_in_range("sensor_angles_deg", a, -90.0, 90.0) for a in sensor_angles_deg)
        angles = np.radians(self.sensor_angles_deg)
        mask = np.zeros(4)
        mask[list(self.sensors)] = 1.0
        law = self.law
        gain = np.array([law.k_side, law.k_mid, law.k_mid, law.k_side]) * mask
        self._cos, self._sin = gain * libm.cos(angles), gain * libm.sin(angles)
        self.structure = observation_layout(observation_space.shape[0])
        self.last_stopped = np.zeros(0, dtype=bool)
        self.last_turn = np.zeros(0)

    def describe(self) -> dict:
        return {"name": type(self).__name__, "ir_scale": self.ir_scale, "sensors": list(self.sensors),
                "sensor_angles_deg": list(self.sensor_angles_deg)}  # fmt: skip

    def initial_memory(self) -> np.ndarray:
        return np.full(1, INITIAL_VELOCITY)

    def goal_force(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The attractive force in the robot's frame: (100, 0), along the heading (the paper's)."""
        n = obs.shape[0]
        return np.full(n, self.law.goal_force), np.zeros(n)

    def extra_force(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forces a subclass adds to the goal and obstacle forces (none in AP-lite)."""
        return 0.0, 0.0

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        batch = obs[None] if single else obs
        n = batch.shape[0]
        v = np.array(state, dtype=np.float64).reshape(-1) if state is not None else None
        if v is None or v.shape != (n,):
            v = np.full(n, INITIAL_VELOCITY)
        if episode_start is not None:
            v[np.broadcast_to(np.asarray(episode_start, dtype=bool), (n,))] = INITIAL_VELOCITY
        actions, v = self.control(batch, v)
        return (actions[0] if single else actions), v[:, None]

    def control(self, obs: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One AP-lite cycle for every row: ``(actions (n, 2) as power / 100, new velocity (n,))``."""
        a, b = self.structure["ir"]
        raw = raw_from_observation(obs[:, a:b], self.ir_scale)
        seen = raw > READING_FILTER
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(seen, np.maximum(self.law.range_in - inches_from_raw(raw), 0.0), 0.0)
        fx, fy = self.goal_force(obs)
        ex, ey = self.extra_force(obs)
        # Sensor by sensor, in order (not a matrix product, whose rounding depends on the batch size).
        for s in range(4):
            fx = fx - r[:, s] * self._cos[s]
            fy = fy - r[:, s] * self._sin[s]
        fx, fy = fx + ex, fy + ey
        vx = self.law.friction * v + STEP * fx / MASS
        vy = STEP * fy / MASS
        v = np.hypot(vx, vy)
        delta = libm.arctan2(STEP * fy / MASS, STEP * fx / MASS)
        delta = np.where(delta == -np.pi, np.pi, delta)
        w = np.where(delta > np.pi / 2, np.pi - delta, np.where(delta < -np.pi / 2, -np.pi - delta, delta))
        theta_new = libm.arctan2(vy, vx)
        moving = (theta_new >= -np.pi / 2) & (theta_new <= np.pi / 2)
        alpha = self.law.alpha
        right = np.trunc(v + v * alpha * w)
        left = np.trunc(v - v * alpha * w)
        over = (right > MAX_SPEED) | (left > MAX_SPEED)
        right_larger = right >= left
        with np.errstate(divide="ignore", invalid="ignore"):
            scaled_left = np.trunc(MAX_SPEED * left / right)
            scaled_right = np.trunc(MAX_SPEED * right / left)
        left, right = (
            np.where(over, np.where(right_larger, scaled_left, MAX_SPEED), left),
            np.where(over, np.where(right_larger, MAX_SPEED, scaled_right), right),
        )
        left = np.where(moving, np.maximum(left, 0.0), 0.0)
        right = np.where(moving, np.maximum(right, 0.0), 0.0)
        self.last_stopped = (left == 0) & (right == 0)
        self.last_turn = w
        return np.column_stack([left, right]).astype(np.float32) / 100.0, v


class APLiteGoalSeeking(APLite):
    """AP-lite whose goal force (100) points at the sensed light instead of along the heading (*ours*): a robot
    that has turned away from the goal turns back. Everything else is :class:`APLite`."""

    def goal_force(self, obs):
        a = self.structure["light"][0]
        bearing = np.pi * obs[:, a]
        return self.law.goal_force * np.cos(bearing), self.law.goal_force * np.sin(bearing)


class FormationController(APLiteGoalSeeking):
    """Physicomimetics formation (Spears et al. 2004; the paper's Section 2): Hooke's-law springs between robots
    plus AP-lite's obstacle and goal forces.

    Between a robot and each robot it senses by trilateration within ``1.5 R``, a spring of magnitude
    ``k |r - R|`` along the line joining them (repulsive below R, attractive above), added to the goal-seeking
    AP-lite forces before AP-lite's velocity and power update (its friction and F = m a step).

    A deviation from the paper's leader-follower wording, on purpose: every robot, the leader included, springs to
    every robot it senses, and the ``leader`` slot of the observation is not read. The paper says "AP-lite is
    specifically designed as a leader-follower algorithm; only the leader broadcasts a signal", but gives no
    follower force law and ran no formation ("All the experiments are conducted with a single robot"; the swarm is
    future work), so the structure is the framework it cites (Spears et al. 2004), where neighbours sense each other.
    Read literally, followers would sense the leader alone: a spring of rest length R to it holds only the first
    ring of a lattice (a robot cannot tell its ring from its own observation) and leaves the ring's spacing to the
    IR. Measured on ``formation_v0``'s defaults, seeds 0-7: the all-pairs springs bring 0.93 of the robots to the
    goal (5 of 8 runs whole), median formation error 0.15 R; leader-only springs 0.70 (3 of 8), 0.29 R.

    Args:
        spacing_m: R, the lattice spacing (the environment's ``spacing_m``).
        spring_k: k per metre of stretch (the feasibility study: 200-400 holds a 7-robot hexagon; below 100 tears).
        comm_range_m: the environment's trilateration range (to read the normalised ranges).
        Others: see :class:`APLite`.
    """

    tunables = FormationTunables

    def __init__(self, observation_space, action_space, *, spacing_m: float = 0.9,
                 spring_k: float = FormationTunables.spring_k, comm_range_m: float = 3.0, **kwargs):  # fmt: skip
        super().__init__(observation_space, action_space, **kwargs)
        self.spacing_m = check_in_range("spacing_m", spacing_m, 0.3, 5.0)
        self.spring_k = check_in_range("spring_k", spring_k, 0.0, 5000.0)
        self.comm_range_m = check_in_range("comm_range_m", comm_range_m, 0.5, 10.0)

    def describe(self) -> dict:
        return {**super().describe(), "spacing_m": self.spacing_m, "spring_k": self.spring_k,
                "comm_range_m": self.comm_range_m}  # fmt: skip

    def extra_force(self, obs):
        a, b = self.structure["neighbours"]
        nb = obs[:, a:b].reshape(obs.shape[0], -1, 3)
        r = nb[..., 0] * self.comm_range_m
        bearing = np.pi * nb[..., 1]
        near = (nb[..., 2] > 0.5) & (r <= 1.5 * self.spacing_m)
        magnitude = np.where(near, self.spring_k * (r - self.spacing_m), 0.0)
        return (magnitude * np.cos(bearing)).sum(axis=1), (magnitude * np.sin(bearing)).sum(axis=1)
