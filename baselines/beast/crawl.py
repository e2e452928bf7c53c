"""The quadruped crawl of a 6-beast with a broken limb (paper section 5), planned from the robot's own sensors.

Paper: Pai, Barman and Ralph, "Platonic Beasts", section 5: "if a 6-beast loses operation of a limb while rolling,
it can simply reorient the body so that the defective limb is on top and no longer used for locomotion, and walk
with the slower quadruped crawl gait." The rolling gait cannot do without the broken limb: every tumble lands the
limb opposite the one it lifts, so with limb k locked its opposite k' can never be lifted, becomes a permanent pivot
and the robot rolls in small circles.

**Stance.** The broken limb k points straight up; its opposite k' (pointing down) is folded sideways under the body,
thigh horizontal and shank turned up past the body's edge, clear of the floor (its shoulder hangs 112 mm under the
body centre, so the body stands ``height`` = 170 mm up); the four equatorial limbs are the legs, each foot on the
floor about ``reach`` from the body's vertical axis along its limb's azimuth (an X-shaped quadruped whose forward
direction lies between two legs), on the knee-up branch (the knee above the shoulder, the links clear of the floor).

**Crawl.** A statically stable, "shift then swing" crawl (McGhee and Frank's creeping gait, the paper's ref. [16]):
one leg at a time, in the lateral-sequence order left-hind, left-front, right-hind, right-front. For each leg:

1. **Shift.** With all four feet planted, the body moves (level, the forward direction kept along the heading) so
   that the centre of mass is a quarter stride further along the heading and inside the triangle of the other three
   feet, at least ``margin`` from its edges (the nearest such point when the forward target is outside). Planted
   limbs follow from the inverse kinematics with feet fixed (:meth:`BeastPlanner.body_motion`).
2. **Swing.** The leg lifts ``lift`` straight up, moves in a lifted arc to its next foothold (half a stride ahead of
   its nominal place under the body's forward target; in steady state each foot stands from half a stride ahead of
   its nominal place to half a stride behind), and sets down a few millimetres into the floor so that it bears load;
   if its contact switch is still off it reaches further down, a centimetre at a time.

**Closed loop.** Every shift and swing is planned from the measured state: foot positions in the body frame by
forward kinematics of the encoder angles, and which feet are down from the contact switches. The footholds are kept
in a ground frame attached to the planted feet (odometry: x along the heading, z up, the floor at z = 0), which the
robot sets up from its feet at the start; before each plan the body pose in that frame is fitted (Kabsch) to the
planted feet's measured positions, so a body that sagged, yawed or slipped is re-levelled and re-aimed, and a foot's
foothold is recorded where it actually landed. The centre of mass is computed from the encoder angles and the
model's link masses. The tilt switches are not needed while standing on four feet: the feet give the floor's plane.

**Reorientation from the rolling stance** (:class:`ReorientController`). From the tasks' three-foot start stance
with the broken limb k free, the support is k's opposite k' and two limbs a, b: a partial roll of about 55 degrees
(the smallest turn that puts k straight up, turned about the vertical so that the heading bisects two legs) on
k', a, b, then c, d (a's and b's opposites, the upper limbs) set down as the front legs, the body moves over the
four legs at the crawl's height, k' lifts and folds, and the crawl takes over (about 25 s). A broken limb that
stands in the start support is locked as a strut and cannot be put on top this way: every turn that lifts it is a
roll over the edge of the other two support feet, whose tip needs the locked limb's joints to move (with them
locked the body can only turn about its foot, which keeps the centre of mass within 0.26 m of that foot, while the
opposite edge is 0.30 m away); a pure roll about an edge that contains the locked limb leaves its joints alone but
keeps it on the floor; and the free limbs cannot push the body over that edge (their shoulders rise beyond their
0.24 m reach of the floor). The controller then holds with ``failure`` set.

Public names: :class:`CrawlConfig`, :class:`CrawlController`, :class:`ReorientController`, :func:`crawl_frame` (the
body-frame forward, left and up directions for a broken limb), :func:`crawl_stance_qpos` (the crawl stance as a
MuJoCo state, for a reset), :func:`centre_of_mass`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from baselines.beast.geometry import kabsch, rotation_exp, rotation_log
from baselines.beast.observation import split_observation
from baselines.beast.planner import TUCKED, BeastPlanner, JointTrajectory
from polyenvs.beast import kinematics as K
from polyenvs.beast.model import CONTROL_DT, BeastModelParams

__all__ = [
    "FOLDED",
    "CrawlConfig",
    "CrawlController",
    "ReorientController",
    "centre_of_mass",
    "body_motion",
    "crawl_frame",
    "crawl_stance_qpos",
]

#: The folded limb opposite the broken one (joints 2 and 3, radians; joint 1 aims it, see :func:`folded_angles`):
#: thigh level with the shoulder, shank turned 70 degrees up, so the foot ends 146 mm out and 20 mm above the body
#: centre; the shank's axis passes 16 mm outside the cube body's lower corner (4 mm clear of its 12 mm capsule), and
#: nothing of the limb hangs lower than its shoulder capsule (132 mm below the body centre).
FOLDED = np.radians([0.0, -70.0])
#: The default 6-beast's model parameters, whose mass model and body the crawl's centre of mass assumes.
_MODEL = BeastModelParams("octahedron")
#: Mass model of the default 6-beast (kg): body, link 1, link 2, link 3, foot.
MASSES = (_MODEL.body_mass, _MODEL.link1_mass, _MODEL.link2_mass, _MODEL.link3_mass, _MODEL.foot_mass)
#: Inradius of the body (m): where link 1 starts along its limb axis.
INRADIUS = _MODEL.inradius


@dataclasses.dataclass(frozen=True)
class CrawlConfig:
    """Parameters of the crawl (metres, degrees, seconds).

    ``height`` is the body centre above the floor: the folded limb's shoulder capsule reaches 132 mm below the
    centre, so 170 mm leaves it 38 mm clear. ``reach`` is the feet's nominal distance from the body's vertical axis,
    70 mm beyond the shoulders, leaving each foot room for ``stride`` along any heading inside the leg's reach on
    the floor (about 150 mm around the point under its shoulder at this height). ``margin`` is the least distance
    of the centre of mass from the edges of the support triangle while a leg swings (it covers the swinging leg's
    own shift of the centre of mass, about 8 mm, and the feet's drift).
    """

    rate_deg_s: float = 20.0
    height: float = 0.17
    reach: float = 0.185
    stride: float = 0.14
    lift: float = 0.03
    margin: float = 0.03
    press: float = 0.004
    settle: float = 0.5
    knots: int = 12


def crawl_frame(disabled: int, heading_rad: float = 0.0, polyhedron: str = "octahedron") -> np.ndarray:
    """Body-frame (forward, left, up) rows (3, 3) of the crawl with 0-based limb ``disabled`` on top.

    Up is the broken limb's axis. Forward is the bisector of the two lowest-numbered perpendicular (non-opposite)
    legs, turned by ``heading_rad`` counter-clockwise about up: an X stance, two legs ahead and two behind.
    """
    dirs = K.limb_directions(polyhedron)
    up = dirs[disabled]
    legs = [i for i in range(len(dirs)) if abs(float(dirs[i] @ up)) < 0.5]
    a = legs[0]
    b = next(i for i in legs[1:] if float(dirs[i] @ dirs[a]) > -0.5)
    forward = dirs[a] + dirs[b]
    forward /= np.linalg.norm(forward)
    left = np.cross(up, forward)
    forward, left = (
        math.cos(heading_rad) * forward + math.sin(heading_rad) * left,
        -math.sin(heading_rad) * forward + math.cos(heading_rad) * left,
    )
    return np.stack([forward, left, up])


def folded_angles(planner: BeastPlanner, limb: int, toward: np.ndarray) -> np.ndarray:
    """Joint angles of ``limb`` folded (:data:`FOLDED`) with its thigh pointing along body direction ``toward``."""
    local = planner.base[limb].T @ toward
    return np.array([math.atan2(local[1], local[0]), *FOLDED])


def centre_of_mass(planner: BeastPlanner, q: np.ndarray, masses=MASSES) -> np.ndarray:
    """The centre of mass in the body frame from the joint angles: body at the centre, each link's mass at its
    midpoint, the foot at the foot centre."""
    body, m1, m2, m3, mf = masses
    frames = K.dh_frames(np.asarray(q, dtype=float).reshape(planner.n_limbs, 3), planner.links)[..., :3, 3]
    shoulder, knee, foot = frames[:, 0], frames[:, 1], frames[:, 2]
    link1 = shoulder * (INRADIUS + planner.links.d1) / (2 * planner.links.d1)
    local = m1 * link1 + m2 * (shoulder + knee) / 2 + m3 * (knee + foot) / 2 + mf * foot
    total = body + planner.n_limbs * (m1 + m2 + m3 + mf)
    return np.einsum("lij,lj->i", planner.base, local) / total


def body_motion(
    planner: BeastPlanner,
    q_now: np.ndarray,
    planted: list[int],
    feet_ground: np.ndarray,
    pose0: tuple[np.ndarray, np.ndarray],
    pose1: tuple[np.ndarray, np.ndarray],
    *,
    free_targets: dict[int, np.ndarray],
    knots: int = 12,
) -> JointTrajectory | None:
    """:meth:`BeastPlanner.body_motion` for the legs, each on the nearest of its four inverse-kinematics solutions
    (a level leg stands with theta3 < 0 on some limbs, where the tumbles' knee branch would need joint 1 at its
    +-180 degree stop); None if a joint would leave its range."""
    traj = planner.body_motion(q_now, planted, feet_ground, pose0, pose1, free_targets, any_branch=True, knots=knots)
    return traj if traj is not None and planner.in_range(traj.q) else None


def leg_trajectory(
    planner: BeastPlanner,
    q: np.ndarray,
    leg: int,
    path: np.ndarray,
    rot: np.ndarray,
    centre: np.ndarray,
    *,
    rate: float,
) -> JointTrajectory | None:
    """Joint trajectory of one leg along a ground-frame foot path (knots, 3), the rest of the robot held at ``q``
    (body pose ``rot``, ``centre``); None if the path leaves the leg's workspace or joint range, or crosses a
    singularity (a jump between solutions)."""
    q0 = q.reshape(planner.n_limbs, 3)
    p_limb = (path - centre) @ rot @ planner.base[leg]  # ground -> body -> limb base frame, row-wise
    if not np.all(K.reachable(p_limb, planner.links, tol=-1e-3)):
        return None
    prev = q0[leg]
    knots = np.repeat(q0[None].copy(), len(path), axis=0)
    for i, point in enumerate(p_limb):
        prev = planner.ik_nearest_any(point[None], prev[None])[0]
        knots[i, leg] = prev
    if np.abs(np.diff(knots[:, leg], axis=0)).max() > 0.6:
        return None
    flat = knots.reshape(len(path), -1)
    if not planner.in_range(flat):
        return None
    dt = np.maximum(np.abs(np.diff(flat, axis=0)).max(axis=1) / rate, 0.02)
    dt[[0, -1]] *= 1.5
    times = np.concatenate([[0.0], np.cumsum(dt)])
    qd = np.zeros_like(flat)
    qd[1:-1] = (flat[2:] - flat[:-2]) / (times[2:] - times[:-2])[:, None]
    return JointTrajectory(times, flat, qd)


def crawl_stance_qpos(
    disabled_limb: int, config: CrawlConfig | None = None, heading_rad: float = 0.0, planner=None
) -> np.ndarray:
    """MuJoCo qpos of the crawl stance with 1-based ``disabled_limb`` straight up, the crawl's forward along world
    +x: body centre ``config.height`` up, the four legs' feet on the floor at ``config.reach`` from the vertical
    axis on the knee-up branch, the opposite limb folded away behind."""
    config = config or CrawlConfig()
    planner = planner or BeastPlanner("octahedron")
    k = disabled_limb - 1
    frame = crawl_frame(k, heading_rad, planner.polyhedron)  # rows: forward, left, up in the body frame
    rot = frame  # world-from-body: body forward -> +x, left -> +y, up -> +z
    q = np.tile(TUCKED, (planner.n_limbs, 1))
    opposite = int(np.argmin(planner.dirs @ planner.dirs[k]))
    q[opposite] = folded_angles(planner, opposite, -crawl_frame(k, 0.0, planner.polyhedron)[0])
    for leg in _legs(planner, k):
        az = rot @ planner.dirs[leg]
        foot_w = np.array([config.reach * az[0], config.reach * az[1], planner.foot_radius - config.height])
        p_limb = planner.base[leg].T @ (rot.T @ foot_w)
        sols = K.ik_solutions(p_limb, planner.links)
        knees = (rot @ planner.base[leg] @ K.dh_frames(sols, planner.links)[:, 1, :3, 3].T)[2]
        # The knee-up solution; of its two mirror forms (theta1 + pi, pi - theta2, -theta3) the one with joint 1
        # nearer mid-range, so that the legs never work against the joint-1 stop at +-180 degrees.
        q[leg] = sols[int(np.argmax(knees - 1e-6 * np.abs(sols[:, 0])))]
    quat = K.rotation_quat(rot)
    return np.concatenate([[0.0, 0.0, config.height], quat, q.ravel()])


def _legs(planner: BeastPlanner, disabled: int) -> list[int]:
    """The four limbs perpendicular to the broken one: the crawl's legs."""
    return [i for i in range(planner.n_limbs) if abs(float(planner.dirs[i] @ planner.dirs[disabled])) < 0.5]


def _cross2(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _inside_triangle(point: np.ndarray, tri: np.ndarray, margin: float) -> np.ndarray:
    """The point of triangle ``tri`` (3, 2), shrunk by ``margin`` about its incentre, nearest ``point``."""
    a, b, c = (np.linalg.norm(tri[(i + 1) % 3] - tri[(i + 2) % 3]) for i in range(3))
    incentre = (a * tri[0] + b * tri[1] + c * tri[2]) / (a + b + c)
    area = abs(_cross2(tri[1] - tri[0], tri[2] - tri[0])) / 2
    r_in = 2 * area / (a + b + c)
    if r_in <= margin:
        return incentre
    small = incentre + (tri - incentre) * (r_in - margin) / r_in
    orient = np.sign(_cross2(small[1] - small[0], small[2] - small[0]))
    if all(orient * _cross2(small[(i + 1) % 3] - small[i], point - small[i]) >= 0 for i in range(3)):
        return point
    best, dist = point, np.inf
    for i in range(3):
        p, e = small[i], small[(i + 1) % 3] - small[i]
        cand = p + np.clip((point - p) @ e / (e @ e), 0.0, 1.0) * e
        if np.linalg.norm(cand - point) < dist:
            best, dist = cand, np.linalg.norm(cand - point)
    return best


class _FootholdController:
    """What the crawl and the reorientation share: a state machine over joint trajectories, the planted feet's
    footholds in a ground frame attached to them, and the body pose fitted to those feet before every plan."""

    def __init__(self, planner: BeastPlanner, disabled_limb: int, config: CrawlConfig | None):
        self.planner = planner
        self.config = config or CrawlConfig()
        self.k = int(disabled_limb)  # 0-based
        self.opposite = int(np.argmin(planner.dirs @ planner.dirs[self.k]))
        self.rate = math.radians(self.config.rate_deg_s)
        self.phase = "settle"
        self.t = 0.0
        self.waited = 0.0
        self.traj: JointTrajectory | None = None
        self.hold_q: np.ndarray | None = None
        self.footholds: dict[int, np.ndarray] = {}  # ground-frame foot centres of the planted legs
        self.reaches = 0

    def _sense(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(encoder angles, feet down) from an observation; the first one's angles are what the robot holds."""
        sensors = split_observation(obs)
        q = sensors["joint_pos"].copy()
        if self.hold_q is None:
            self.hold_q = q.copy()
        return q, sensors["foot_contact"] > 0.5

    def _pose(self, q: np.ndarray, legs) -> tuple[np.ndarray, np.ndarray]:
        """Body pose (rot body -> ground, centre) fitted to the measured feet of ``legs`` and their footholds."""
        return kabsch(self.planner.feet(q)[list(legs)], np.stack([self.footholds[leg] for leg in legs]))

    def _feet_array(self) -> np.ndarray:
        out = np.zeros((self.planner.n_limbs, 3))
        for leg, pos in self.footholds.items():
            out[leg] = pos
        return out

    def _set_down(self, q: np.ndarray, leg: int, standing) -> None:
        """Record where ``leg``'s foot stands, in the ground frame (from the ``standing`` feet), on the floor."""
        rot, centre = self._pose(q, standing)
        pos = rot @ self.planner.feet(q)[leg] + centre
        pos[2] = self.planner.foot_radius
        self.footholds[leg] = pos

    def _leg_trajectory(self, q, leg, path, rot, centre) -> JointTrajectory | None:
        return leg_trajectory(self.planner, q, leg, path, rot, centre, rate=self.rate)

    def _start(self, traj: JointTrajectory, phase: str):
        self.traj, self.t, self.phase = traj, 0.0, phase


class CrawlController(_FootholdController):
    """The closed-loop crawl for one environment: ``controller(obs) -> action`` every 10 ms tick.

    Phases: ``settle`` (hold the start pose, then set up the ground frame from the feet), ``shift`` (body over the
    next support triangle), ``swing`` (one leg to its next foothold), ``reach`` (the swung foot has not touched: reach
    further down), then the next leg. ``steps`` counts completed leg swings, ``cycles`` full crawl cycles.
    """

    def __init__(
        self,
        planner: BeastPlanner,
        disabled_limb: int,
        config: CrawlConfig | None = None,
        heading_rad: float = 0.0,
        max_cycles: int | None = None,
        fold: np.ndarray | None = None,
    ):
        super().__init__(planner, disabled_limb, config)
        self.legs = _legs(planner, self.k)
        self.frame = crawl_frame(self.k, heading_rad, planner.polyhedron)
        if fold is None:
            fold = folded_angles(planner, self.opposite, -crawl_frame(self.k, 0.0, planner.polyhedron)[0])
        self.fold = np.asarray(fold, dtype=float)
        self.order = self._crawl_order()
        self.max_cycles = max_cycles
        self.steps = 0
        self.swing_leg: int | None = None
        self.forward_target: np.ndarray | None = None
        self.failures = 0

    @property
    def cycles(self) -> int:
        return self.steps // 4

    def _crawl_order(self) -> list[int]:
        """Legs in the lateral-sequence crawl order: left-hind, left-front, right-hind, right-front (McGhee and
        Frank: the order whose support triangles are widest for a given stride)."""
        fwd, left, _ = self.frame
        angle = {leg: math.atan2(left @ self.planner.dirs[leg], fwd @ self.planner.dirs[leg]) for leg in self.legs}
        # Left-front: the leg nearest 45 degrees; the others follow at +90 (left-hind), 180 and -90 degrees.
        lf = min(self.legs, key=lambda leg: abs(math.remainder(angle[leg] - math.pi / 4, 2 * math.pi)))
        at = {round(math.remainder(angle[leg] - angle[lf], 2 * math.pi) / (math.pi / 2)) % 4: leg for leg in self.legs}
        return [at[1], at[0], at[2], at[3]]

    # ------------------------------------------------------------------------------------------------ the loop
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        p, cfg = self.planner, self.config
        q, contact = self._sense(obs)
        if self.phase == "settle":
            self.waited += CONTROL_DT
            if self.waited >= cfg.settle:
                self._start_ground(q)
                self._plan_shift(q)
        elif self.phase in ("shift", "swing", "reach"):
            self.t += CONTROL_DT
            if self.t >= self.traj.duration:
                self.hold_q = self.traj.q[-1].copy()
                if self.phase == "shift":
                    self._plan_swing(q)
                elif contact[self.swing_leg] or self.reaches >= 4:
                    self._landed(q)
                    if self.max_cycles is not None and self.cycles >= self.max_cycles:
                        self.phase = "done"
                    else:
                        self._plan_shift(q)
                else:
                    self._plan_reach(q)
        elif self.phase == "stuck":
            self.waited += CONTROL_DT
            if self.waited >= 1.0:
                self.waited = 0.0
                self._plan_shift(q)
        if self.traj is not None and self.phase in ("shift", "swing", "reach"):
            return p.to_action(self.traj(self.t))
        return p.to_action(self.hold_q)

    # ------------------------------------------------------------------------------------------------ geometry
    def _start_ground(self, q: np.ndarray):
        """The ground frame from the four feet: floor plane fitted to them, x along the heading, origin on the
        floor under the body centre."""
        r = self.planner.foot_radius
        feet = self.planner.feet(q)[self.legs]
        centre = feet.mean(axis=0)
        normal = np.linalg.svd(feet - centre)[2][2]
        normal = normal if normal @ -centre > 0 else -normal
        x = self.frame[0] - (self.frame[0] @ normal) * normal
        x /= np.linalg.norm(x)
        rot = np.stack([x, np.cross(normal, x), normal])  # body -> ground
        origin = (centre @ normal) * normal - r * normal  # on the floor, under the body centre
        self.footholds = {leg: rot @ (feet[i] - origin) for i, leg in enumerate(self.legs)}
        for leg in self.legs:
            self.footholds[leg][2] = r

    def _level(self) -> np.ndarray:
        """Rotation body -> ground of the level body facing the heading."""
        return self.frame.copy()

    def _nominal(self, leg: int) -> np.ndarray:
        """A leg's nominal foot place relative to the centre of mass, in the ground frame (x, y)."""
        az = self._level() @ self.planner.dirs[leg]
        return self.config.reach * az[:2] / np.linalg.norm(az[:2])

    # ------------------------------------------------------------------------------------------------ planning
    def _plan_shift(self, q: np.ndarray):
        """Body over the triangle of the three legs that stay down while the next leg swings."""
        p, cfg = self.planner, self.config
        leg = self.order[self.steps % 4]
        pose0 = self._pose(q, self.legs)
        rot1 = self._level()
        xy = np.stack([self.footholds[i][:2] for i in self.legs])
        # Steady state: just before a leg lifts, the feet sit (relative to the body's forward progress) at +1/4,
        # 0, -1/4 and -1/2 stride about their nominal places, so the body stands 1/8 stride ahead of the feet's
        # centroid; the nominal places themselves are centred on the centre of mass.
        forward = xy.mean(axis=0) + np.array([cfg.stride / 8, 0.0])
        tri = np.stack([self.footholds[i][:2] for i in self.legs if i != leg])
        com_xy = _inside_triangle(forward, tri, cfg.margin)
        q_end = q.reshape(p.n_limbs, 3).copy()
        q_end[self.opposite] = self.fold
        com = rot1 @ centre_of_mass(p, q_end)
        centre = np.array([com_xy[0] - com[0], com_xy[1] - com[1], cfg.height])
        traj = body_motion(
            p, q, self.legs, self._feet_array(), pose0, (rot1, centre), free_targets={self.opposite: self.fold},
            knots=cfg.knots,
        )  # fmt: skip
        if traj is None:
            self.failures += 1
            self.phase, self.waited = "stuck", 0.0
            return
        self.forward_target = forward
        self.swing_leg = leg
        self._start(traj, "shift")

    def _plan_swing(self, q: np.ndarray):
        """The swing leg's lifted arc to its next foothold, the body still."""
        p, cfg = self.planner, self.config
        leg = self.swing_leg
        support = [i for i in self.legs if i != leg]
        rot, centre = self._pose(q, support)
        feet = p.feet(q)
        start = rot @ feet[leg] + centre
        base = self.forward_target + self._nominal(leg)
        for scale in (1.0, 0.75, 0.5, 0.25, 0.0):
            goal = np.array([*(base + np.array([scale * cfg.stride / 2, 0.0])), p.foot_radius - cfg.press])
            path = self._arc(start, goal)
            traj = self._leg_trajectory(q, leg, path, rot, centre)
            if traj is not None:
                self.reaches = 0
                self._start(traj, "swing")
                return
        self.failures += 1
        self.phase, self.waited = "stuck", 0.0

    def _plan_reach(self, q: np.ndarray):
        """The swung foot has not touched down: reach 1 cm further down."""
        p = self.planner
        leg = self.swing_leg
        rot, centre = self._pose(q, [i for i in self.legs if i != leg])
        start = rot @ p.feet(q)[leg] + centre
        goal = start - np.array([0.0, 0.0, 0.01])
        self.reaches += 1
        traj = self._leg_trajectory(q, leg, np.linspace(start, goal, 4), rot, centre)
        if traj is None:
            self.reaches = 4
            self.hold_q = q.copy()
            self.traj = None
            self._landed(q)
            self._plan_shift(q)
            return
        self._start(traj, "reach")

    def _landed(self, q: np.ndarray):
        """Record where the swung foot stands, in the ground frame (from the other three feet), on the floor."""
        leg = self.swing_leg
        self._set_down(q, leg, [i for i in self.legs if i != leg])
        self.steps += 1

    def _arc(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Foot path (knots, 3): straight up to the lift height, across, straight down (smooth blends)."""
        cfg = self.config
        s = np.linspace(0.0, 1.0, 2 * cfg.knots + 1)
        top = max(start[2], goal[2]) + cfg.lift
        smooth = lambda u: 3 * np.clip(u, 0, 1) ** 2 - 2 * np.clip(u, 0, 1) ** 3  # noqa: E731
        across = smooth((s - 0.2) / 0.6)
        z = np.where(
            s < 0.5,
            start[2] + (top - start[2]) * smooth(s / 0.25),
            top + (goal[2] - top) * smooth((s - 0.75) / 0.25),
        )
        xy = start[:2] + across[:, None] * (goal[:2] - start[:2])
        return np.column_stack([xy, z])

    def _leg_trajectory(self, q, leg, path, rot, centre) -> JointTrajectory | None:
        q = q.reshape(self.planner.n_limbs, 3).copy()
        q[self.opposite] = self.fold
        return super()._leg_trajectory(q, leg, path, rot, centre)


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b``."""
    axis = np.cross(a, b)
    s, c = float(np.linalg.norm(axis)), float(np.clip(a @ b, -1.0, 1.0))
    if s < 1e-12:
        return np.eye(3)
    return rotation_exp(axis / s * math.atan2(s, c))


class ReorientController(_FootholdController):
    """From the 6-beast's three-foot rolling stance to the crawl stance with the broken limb on top, then the crawl.

    For a broken limb k that is free (pointing up) in the start stance, the support is k's opposite k' and two
    limbs a, b; the other two free limbs c, d are a's and b's opposites. The body turns by the angle between k and
    the vertical (54.7 degrees from a symmetric rolling stance) about the horizontal axis perpendicular to k, the
    smallest rotation that puts k straight up; a and b become the crawl's rear legs, c and d come down in front as
    the other two legs, and k' (then pointing straight down) is lifted and folded. Steps, each planned from the
    measured state (feet by forward kinematics of the encoders in a ground frame set up from the start feet, the
    body pose fitted to the planted feet before every plan, as the crawl does):

    1. ``tilt``: on k', a, b the body turns part of the way (``fraction``) and sinks to ``tilt_height``, c and d
       swing to a pose above their footholds;
    2. ``place``: c, then d, set down on their footholds (reaching further down until the contact switch is on);
    3. ``shift``: on all five feet the body turns the rest of the way, to the crawl stance's height, centre of mass
       over the middle of a, b, c, d;
    4. ``lift``: k' lifts off the floor and folds;

    then :class:`CrawlController` takes over, heading along the start stance's forward direction (the task's
    heading) turned by ``heading_rad``.
    """

    def __init__(
        self,
        planner: BeastPlanner,
        disabled_limb: int,
        start_forward: np.ndarray,
        *,
        config: CrawlConfig | None = None,
        heading_rad: float = 0.0,
        max_cycles: int | None = None,
        fraction: float = 0.5,
        tilt_height: float = 0.15,
    ):
        super().__init__(planner, disabled_limb, config)
        self.start_forward = np.asarray(start_forward, dtype=float)
        self.heading_rad = heading_rad
        self.max_cycles = max_cycles
        self.fraction = fraction
        self.tilt_height = tilt_height
        self.crawl: CrawlController | None = None
        self.placing: int | None = None
        self.failure: str | None = None
        self.reoriented_at: float | None = None
        self.elapsed = 0.0

    # ------------------------------------------------------------------------------------------------ the loop
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.elapsed += CONTROL_DT
        if self.crawl is not None:
            return self.crawl(obs)
        q, contact = self._sense(obs)
        if self.phase == "settle":
            self.waited += CONTROL_DT
            if self.waited >= self.config.settle:
                self._start_ground(q, contact)
                if self.phase != "failed":
                    self._plan_tilt(q)
        elif self.phase in ("tilt", "place", "reach", "shift", "lift"):
            self.t += CONTROL_DT
            if self.t >= self.traj.duration:
                self.hold_q = self.traj.q[-1].copy()
                if self.phase == "lift":
                    self._hand_over(obs, q)
                    return self.crawl(obs)
                self._plan_after(q, contact)
        if self.traj is not None and self.phase in ("tilt", "place", "reach", "shift", "lift"):
            return self.planner.to_action(self.traj(self.t))
        return self.planner.to_action(self.hold_q)

    def _plan_after(self, q: np.ndarray, contact: np.ndarray):
        """The move of phase tilt, place, reach or shift ended: plan the next one (tilt, place c, place d, shift,
        lift), reaching further down where a placed foot has not touched yet."""
        if self.phase == "tilt":
            self._plan_place(q, self.c)
        elif self.phase == "shift":
            self._plan_lift(q)
        elif contact[self.placing] or self.reaches >= 4:  # place or reach
            self._landed(q)
            if self.placing == self.c:
                self._plan_place(q, self.d)
            else:
                self._plan_shift(q)
        else:
            self._plan_reach(q)

    # ------------------------------------------------------------------------------------------------ geometry
    def _start_ground(self, q: np.ndarray, contact: np.ndarray):
        p, r = self.planner, self.planner.foot_radius
        down = [int(i) for i in np.flatnonzero(contact)]
        limbs = [i + 1 for i in down]
        if self.k in down:
            self.phase, self.failure = "failed", f"the broken limb stands in the support {limbs}: locked, it stays down"
            return
        if self.opposite not in down or len(down) != 3:
            self.phase, self.failure = "failed", f"support {limbs} is not the broken limb's opposite and two others"
            return
        self.support = down
        a, b = (i for i in down if i != self.opposite)
        self.a, self.b = a, b
        self.c = int(np.argmin(p.dirs @ p.dirs[a]))
        self.d = int(np.argmin(p.dirs @ p.dirs[b]))
        self.legs = [a, b, self.c, self.d]
        feet = p.feet(q)[down]
        centre = feet.mean(axis=0)
        normal = np.linalg.svd(feet - centre)[2][2]
        normal = normal if normal @ -centre > 0 else -normal
        x = self.start_forward - (self.start_forward @ normal) * normal
        x /= np.linalg.norm(x)
        rot = np.stack([x, np.cross(normal, x), normal])
        origin = (centre @ normal) * normal - r * normal
        self.footholds = {leg: rot @ (feet[i] - origin) for i, leg in enumerate(down)}
        for leg in down:
            self.footholds[leg][2] = r
        self.rot0 = rot
        self.q0 = q.copy()

    def _aim(self, yaw: float):
        """The crawl stance turned by ``yaw`` about the vertical from the smallest turn that puts k straight up: its
        rotation, body position on the floor (x, y) and the footholds of c and d; the rear legs a, b where they
        stand (their mean offset from the nominal places fixes the body's position)."""
        p, cfg, r = self.planner, self.config, self.planner.foot_radius
        self.rot1 = K.rot_z(yaw) @ _rotation_between(self.rot0 @ p.dirs[self.k], np.array([0.0, 0.0, 1.0])) @ self.rot0
        az = {leg: (self.rot1 @ p.dirs[leg])[:2] for leg in self.legs}
        az = {leg: v / np.linalg.norm(v) for leg, v in az.items()}
        xy = np.mean([self.footholds[leg][:2] - cfg.reach * az[leg] for leg in (self.a, self.b)], axis=0)
        self.target_xy = xy
        self.targets = {leg: np.array([*(xy + cfg.reach * az[leg]), r - cfg.press]) for leg in (self.c, self.d)}

    def _snap_yaw(self) -> float:
        """The yaw that makes the crawl's heading (the ground x turned by heading_rad) bisect two legs: the crawl is
        widest and fastest along a diagonal of its X stance."""
        self._aim(0.0)
        fwd = self.rot1 @ crawl_frame(self.k, 0.0, self.planner.polyhedron)[0]
        off = math.atan2(fwd[1], fwd[0]) - self.heading_rad
        return -math.remainder(off, math.pi / 2)

    def _centre_for(self, rot: np.ndarray, q_end: np.ndarray, com_xy: np.ndarray, height: float) -> np.ndarray:
        com = rot @ centre_of_mass(self.planner, q_end)
        return np.array([com_xy[0] - com[0], com_xy[1] - com[1], height])

    # ------------------------------------------------------------------------------------------------ planning
    def _fail(self, why: str):
        self.phase, self.failure, self.traj = "failed", why, None

    def _plan_tilt(self, q: np.ndarray):
        """The first step, for the largest fraction of the snapping yaw whose tilt and final shift are plannable."""
        snap = self._snap_yaw()
        for share in (1.0, 0.75, 0.5, 0.25, 0.0):
            self._aim(share * snap)
            traj = self._tilt(q)
            if traj is not None:
                self.yaw = share * snap
                return self._start(traj, "tilt")
        self._fail("tilt not plannable")

    def _tilt(self, q: np.ndarray) -> JointTrajectory | None:
        p, cfg = self.planner, self.config
        pose0 = self._pose(q, self.support)
        turn = rotation_log(self.rot1 @ pose0[0].T)
        rot = rotation_exp(self.fraction * turn) @ pose0[0]
        centre = pose0[1] + self.fraction * (np.array([*self.target_xy, 0.0]) - pose0[1] * [1, 1, 0])
        centre[2] = self.tilt_height
        free = {}
        for leg in (self.c, self.d):
            # Above the foothold, in joint space: the foot lift higher than its target.
            above = self.targets[leg] + np.array([0.0, 0.0, 0.05])
            p_limb = p.base[leg].T @ (rot.T @ (above - centre))
            if not K.reachable(p_limb[None], p.links, tol=-1e-3)[0]:
                return None
            free[leg] = p.ik_nearest_any(p_limb[None], TUCKED[None])[0]
        traj = body_motion(
            p, q, self.support, self._feet_array(), pose0, (rot, centre), free_targets=free, knots=cfg.knots
        )
        if traj is None:
            return None
        # The shift onto the four legs at the end must be plannable too (c and d on their footholds).
        feet = self._feet_array()
        for leg in (self.c, self.d):
            feet[leg] = self.targets[leg] * [1, 1, 0] + [0, 0, p.foot_radius]
        q_end = traj.q[-1]
        com_xy = np.mean([feet[leg][:2] for leg in self.legs], axis=0)
        centre1 = self._centre_for(self.rot1, q_end, com_xy, cfg.height)
        planted = self.support + [self.c, self.d]
        pose1 = (self.rot1, centre1)
        if body_motion(p, q_end, planted, feet, (rot, centre), pose1, free_targets={}, knots=cfg.knots) is None:
            return None
        return traj

    def _plan_place(self, q: np.ndarray, leg: int):
        planted = [i for i in self.footholds]
        rot, centre = self._pose(q, planted)
        start = rot @ self.planner.feet(q)[leg] + centre
        goal = self.targets[leg]
        s = np.linspace(0.0, 1.0, 2 * self.config.knots + 1)[:, None]
        smooth = 3 * s**2 - 2 * s**3
        path = start + smooth * (goal - start)
        traj = self._leg_trajectory(q, leg, path, rot, centre)
        if traj is None:
            return self._fail(f"limb {leg + 1} cannot reach its foothold")
        self.placing, self.reaches = leg, 0
        self._start(traj, "place")

    def _plan_reach(self, q: np.ndarray):
        leg = self.placing
        rot, centre = self._pose(q, list(self.footholds))
        start = rot @ self.planner.feet(q)[leg] + centre
        self.reaches += 1
        traj = self._leg_trajectory(q, leg, np.linspace(start, start - [0.0, 0.0, 0.01], 4), rot, centre)
        if traj is None:
            self.reaches = 4
            self._landed(q)
            return self._plan_place(q, self.d) if leg == self.c else self._plan_shift(q)
        self._start(traj, "reach")

    def _landed(self, q: np.ndarray):
        self._set_down(q, self.placing, list(self.footholds))

    def _plan_shift(self, q: np.ndarray):
        p, cfg = self.planner, self.config
        planted = self.support + [self.c, self.d]
        pose0 = self._pose(q, planted)
        com_xy = np.mean([self.footholds[leg][:2] for leg in self.legs], axis=0)
        centre = self._centre_for(self.rot1, q, com_xy, cfg.height)
        traj = body_motion(
            p, q, planted, self._feet_array(), pose0, (self.rot1, centre), free_targets={}, knots=cfg.knots
        )
        if traj is None:
            return self._fail("shift onto the four legs not plannable")
        self._start(traj, "shift")

    def _plan_lift(self, q: np.ndarray):
        """k' lifts 4 cm straight up, bends into the fold (joint 1 kept), then turns to the diagonal between two
        legs nearest it: a short turn that keeps its shank clear of the legs."""
        p = self.planner
        rot, centre = self._pose(q, self.legs)
        k2 = self.opposite
        start = rot @ p.feet(q)[k2] + centre
        up = self._leg_trajectory(q, k2, np.linspace(start, start + [0.0, 0.0, 0.04], 6), rot, centre)
        if up is None:
            return self._fail("cannot lift the opposite limb")
        q_up = up.q[-1].reshape(p.n_limbs, 3)
        options = []
        for i, a in enumerate(self.legs):
            for b in self.legs[i + 1 :]:
                if float(p.dirs[a] @ p.dirs[b]) > -0.5:
                    fold = folded_angles(p, k2, (p.dirs[a] + p.dirs[b]) / math.sqrt(2))
                    for turns in (-1, 0, 1):
                        theta1 = fold[0] + 2 * math.pi * turns
                        if p.joint_ranges[0, 0] <= theta1 <= p.joint_ranges[0, 1]:
                            options.append(np.array([theta1, *fold[1:]]))
        self.fold = min(options, key=lambda f: abs(f[0] - q_up[k2, 0]))
        bent = np.array([q_up[k2, 0], *self.fold[1:]])
        knots = [up.q]
        for target in (bent, self.fold):
            stage = np.repeat(q_up.reshape(1, -1), 7, axis=0).reshape(7, p.n_limbs, 3)
            begin = knots[-1][-1].reshape(p.n_limbs, 3)[k2]
            stage[:, k2] = begin + np.linspace(0.0, 1.0, 7)[:, None] * (target - begin)
            knots.append(stage.reshape(7, -1)[1:])
        flat = np.concatenate(knots)
        dt = np.maximum(np.abs(np.diff(flat, axis=0)).max(axis=1) / self.rate, 0.02)
        times = np.concatenate([[0.0], np.cumsum(dt)])
        self._start(JointTrajectory(times, flat, np.zeros_like(flat)), "lift")

    def _hand_over(self, obs, q):
        """The crawl takes over, heading along the ground frame's x (the start's forward) turned by heading_rad."""
        rot, _ = self._pose(q, self.legs)
        fwd0, left0, _ = crawl_frame(self.k, 0.0, self.planner.polyhedron)
        x_body = rot.T @ np.array([1.0, 0.0, 0.0])
        heading = math.atan2(float(left0 @ x_body), float(fwd0 @ x_body)) + self.heading_rad
        self.reoriented_at = self.elapsed
        self.crawl = CrawlController(self.planner, self.k, self.config, heading, self.max_cycles, self.fold)
        self.crawl.hold_q = self.hold_q.copy()
        self.phase = "crawl"
