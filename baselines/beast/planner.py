"""The rolling gait's planner: tumble geometry, the look-ahead's joint-1 bookkeeping and the joint trajectories.

:class:`BeastPlanner` holds one beast's geometry and plans (no state between calls but caches: of plannable tumbles,
and of its last body motions, since one decision plans the same motion up to three times);
:mod:`baselines.beast.gait` describes the algorithm and runs it closed loop. Public names: :class:`GaitConfig`
(rates, stance, tip keyframes, stance branch), ``DEFAULT_CONFIGS`` (per beast), :class:`BeastPlanner`,
:class:`JointTrajectory` (piecewise cubic), ``TUCKED`` (a free limb's pose).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from baselines.beast.geometry import kabsch, rotation_exp, rotation_log, unit
from polyenvs.beast import kinematics as K
from polyenvs.beast.model import BeastModelParams

__all__ = ["DEFAULT_CONFIGS", "TUCKED", "BeastPlanner", "GaitConfig", "JointTrajectory"]

#: The default model's parameters: its joint limits (radians, rows joint 1, 2, 3) and foot radius are the planner's
#: defaults (the policies read the limits off the observation space, which bounds the encoder angles by them).
_MODEL = BeastModelParams()
#: Per-geometry planning caches (BeastPlanner.plannable, BeastPlanner.sweeps), shared by every planner of that geometry.
_PLANNABLE: dict = {}
#: The free limb's pose on top: straight out along its face normal, clear of the ground and the other limbs.
TUCKED = K.STRAIGHT_OUT
#: Body motions a planner remembers (:meth:`BeastPlanner.body_motion`): a decision's look-ahead plans a candidate's tip
#: and stance, then the chosen tip again, and the tip plan checks the stance that the look-ahead planned; one decision
#: plans about 20 distinct motions, and every entry is a few kilobytes.
MOTION_CACHE = 64


def _read_only(values) -> np.ndarray:
    array = np.array(values, dtype=float)  # a copy: the caller's array stays writable
    array.flags.writeable = False
    return array


class JointTrajectory:
    """Piecewise cubic Hermite joint trajectory through knots (times, angles, velocities); holds the end after T."""

    def __init__(self, times: np.ndarray, q: np.ndarray, qd: np.ndarray):
        self.times, self.q, self.qd = (_read_only(a) for a in (times, q, qd))  # a planner reuses its trajectories

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def __call__(self, t: float) -> np.ndarray:
        if t >= self.times[-1]:
            return self.q[-1].copy()
        if t <= 0.0:
            return self.q[0].copy()
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        h = self.times[i + 1] - self.times[i]
        u = (t - self.times[i]) / h
        h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
        h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
        return h00 * self.q[i] + h10 * h * self.qd[i] + h01 * self.q[i + 1] + h11 * h * self.qd[i + 1]


@dataclasses.dataclass(frozen=True)
class GaitConfig:
    """Parameters of the rolling gait (lengths in metres, angles in degrees).

    The 4-beast's defaults are the feasibility study's working tumble: feet on an equilateral pattern of side 300 mm
    (the nominal 353 mm stance admits no tumble with Table 1's limbs), body centre 168 mm up, a tip keyframe with the
    body centre at (-0.4, 2.3, 146.3) mm in the tumble frame turned by Ry(41.95) Rx(-0.03) Rz(2.68) from the stance
    (centre of mass about 4 mm past the edge), the landing foot pre-placed for a free roll of 16.7 degrees, joints
    at 20 deg/s (the paper's 12 W power budget implies about 15 deg/s).
    """

    rate_deg_s: float = 20.0
    stance_side: float = 0.300
    stance_height: float = 0.168
    tip_centre: tuple[float, float, float] = (-0.0004, 0.0023, 0.1463)
    tip_rotation_deg: tuple[float, float, float] = (41.95, -0.03, 2.68)
    roll_deg: float = 16.7
    #: further (tip_centre, tip_rotation_deg, roll_deg) keyframes tried in order when the first is not plannable,
    #: e.g. from a start stance wider than the nominal one
    tip_alternatives: tuple = ()
    knots: int = 16
    #: which knee-branch solution a stance limb takes: "knee" (the knee higher above the ground) or "centred"
    #: (joint 1 nearer the middle of its range, leaving it room to turn through the tumbles)
    stance_branch: str = "knee"
    #: extra forward motion when the body has not tipped after a plan (metres per retry) and the retries allowed
    nudge: float = 0.006
    max_nudges: int = 4


#: Per-polyhedron defaults. The 6-beast's come from a search over stance and tip keyframe (kinematic checks: every
#: limb in reach and range, body and free feet clear of the floor, centre of mass 4 mm past the edge at the tip and
#: over 20 mm inside the new support after the roll, planted feet at least 35 mm off their joint-1 axes), then
#: MuJoCo runs: a narrow stance (side 240 mm) with the body 200 mm up, since its cube body's lowest corner hangs 147 mm
#: below the centre, and stance limbs on the "centred" branch, from which all 24 of its tumbles are plannable. Its
#: alternative keyframes tip from wider patterns such as the tasks' start stance (side 346 mm); landing at the
#: nominal apex brings the feet back to the nominal pattern.
DEFAULT_CONFIGS = {
    "tetrahedron": GaitConfig(),
    "octahedron": GaitConfig(
        stance_side=0.24,
        stance_height=0.20,
        tip_centre=(0.0025, 0.0, 0.19),
        tip_rotation_deg=(15.0, 0.0, 0.0),
        roll_deg=12.0,
        stance_branch="centred",
        tip_alternatives=(
            ((0.0013, 0.0, 0.18), (20.0, 0.0, 0.0), 15.0),
            ((0.002, 0.0, 0.18), (15.0, 0.0, 0.0), 15.0),
            ((0.0007, 0.0, 0.17), (25.0, 0.0, 0.0), 10.0),
        ),
    ),
    "cube": GaitConfig(),
}


def _motion_key(q_now, planted, feet_tumble, pose0, pose1, free_targets, *, any_branch, knots) -> tuple:
    """Everything :meth:`BeastPlanner.body_motion` reads, exactly (the arrays' bytes)."""
    arrays = (q_now, feet_tumble, *pose0, *pose1, *free_targets.values())
    data = b"".join(np.ascontiguousarray(a, dtype=float).tobytes() for a in arrays)
    return data, tuple(planted), tuple(free_targets), any_branch, knots


class BeastPlanner:
    """Geometry and trajectory planning for one beast (no state between calls but its caches)."""

    def __init__(
        self,
        polyhedron: str = "tetrahedron",
        links: K.Links = K.PROTOTYPE_LINKS,
        joint_ranges: np.ndarray = _MODEL.joint_ranges,
        foot_radius: float = _MODEL.foot_radius,
        config: GaitConfig | None = None,
    ):
        self.polyhedron = polyhedron
        self.links = K.Links(*links)
        self.joint_ranges = np.asarray(joint_ranges, dtype=float)
        self.foot_radius = float(foot_radius)
        self.config = config if config is not None else DEFAULT_CONFIGS[polyhedron]
        self.base = K.limb_base_frames(polyhedron)[:, :3, :3]
        self.dirs = K.limb_directions(polyhedron)
        self.n_limbs = len(self.dirs)
        self.rate = math.radians(self.config.rate_deg_s)
        self._low = np.tile(self.joint_ranges[:, 0], self.n_limbs)
        self._high = np.tile(self.joint_ranges[:, 1], self.n_limbs)
        self._sweeps: dict | None = None
        self._motions: dict[tuple, JointTrajectory | None] = {}  # oldest first; see MOTION_CACHE

    # ----------------------------------------------------------------------------------------------- geometry
    def feet(self, q: np.ndarray) -> np.ndarray:
        """Foot centres in the body frame (n_limbs, 3) from joint angles (n_joints,)."""
        return K.foot_in_body(np.asarray(q, dtype=float).reshape(self.n_limbs, 3), self.links, self.polyhedron)

    def to_action(self, q: np.ndarray) -> np.ndarray:
        """Joint targets -> actions in [-1, 1] (the environments' linear map onto the joint ranges)."""
        return np.clip(2 * (q - self._low) / (self._high - self._low) - 1, -1.0, 1.0).astype(np.float32)

    def order_edge(self, feet: np.ndarray, a: int, b: int, c: int) -> tuple[int, int, int]:
        """(l1, l2, l3) with edge {a, b} ordered so that the ground frame's z = y x (p3 - p1) points to the body."""
        z = np.cross(feet[b] - feet[a], feet[c] - feet[a])
        return (a, b, c) if np.dot(z, -feet[a]) > 0 else (b, a, c)

    def tumble_frame(self, feet: np.ndarray, l1: int, l2: int, l3: int) -> tuple[np.ndarray, np.ndarray]:
        """Rotation body -> tumble frame (rows x, y, z in body coordinates) and the frame origin in the body frame."""
        y = unit(feet[l2] - feet[l1])
        z = unit(np.cross(y, feet[l3] - feet[l1]))
        x = np.cross(y, z)
        origin = (feet[l1] + feet[l2]) / 2 - self.foot_radius * z
        return np.stack([x, y, z]), origin

    def up_axis(self, support) -> np.ndarray:
        """The body-frame direction that points up in the nominal stance on ``support``."""
        return unit(-self.dirs[list(support)].sum(axis=0))

    def stance_orientation(self, l1: int, l2: int, l3: int) -> np.ndarray:
        """Body -> tumble rotation of the nominal stance on (l1, l2, l3): symmetric, the edge l1-l2 ahead."""
        z = self.up_axis((l1, l2, l3))
        y = self.dirs[l2] - self.dirs[l1]
        y = unit(y - np.dot(y, z) * z)
        return np.stack([np.cross(y, z), y, z])

    def nominal_feet(self, l1: int, l2: int, l3: int) -> tuple[np.ndarray, np.ndarray]:
        """Nominal stance feet of (l1, l2, l3) in the body frame (3, 3) and the body centre in the tumble frame."""
        s, r = self.config.stance_side, self.foot_radius
        tumble = np.array([[0.0, -s / 2, r], [0.0, s / 2, r], [-s * math.sqrt(3) / 2, 0.0, r]])
        centre = np.array([-s / (2 * math.sqrt(3)), 0.0, self.config.stance_height])
        rot = self.stance_orientation(l1, l2, l3)
        return (tumble - centre) @ rot, centre

    def stance_angles(self, support) -> dict[int, np.ndarray]:
        """Joint angles of the nominal stance on ``support``, by limb: of the two knee-branch (theta3 > 0) solutions,
        the one with the knee higher above the ground (the working tumble's K0 for the 4-beast), clear of the floor."""
        feet = self.dirs * 0.2  # feet lie roughly along their limb axes; enough to order the triangle
        l1, l2, l3 = self.order_edge(feet, *support)
        limbs = [l1, l2, l3]
        nominal, _ = self.nominal_feet(l1, l2, l3)
        p_limb = np.einsum("lji,lj->li", self.base[limbs], nominal)
        sols = K.inverse_kinematics(p_limb[:, None, :], self.links, knee=1, flip=np.array([False, True]))
        knees = np.einsum("lij,lsj->lsi", self.base[limbs], K.dh_frames(sols, self.links)[..., 1, :3, 3])
        if self.config.stance_branch == "knee":
            best = np.argmax(knees @ self.up_axis(limbs), axis=1)
        else:
            best = np.argmin(np.abs(sols[..., 0]), axis=1)
        return {limb: sols[i, best[i]] for i, limb in enumerate(limbs)}

    def landing_limb(self, l1: int, l2: int, l3: int) -> int:
        """The free limb that lands in tumble (l1 l2 l3 .): the one pointing furthest from l3 (opposite it on the
        6-beast, the only free one on the 4-beast)."""
        free = [limb for limb in range(self.n_limbs) if limb not in (l1, l2, l3)]
        return min(free, key=lambda limb: float(self.dirs[limb] @ self.dirs[l3]))

    def roll_on_paper(self, pts: dict, tumble) -> dict:
        """Ground positions (2-D, by limb l1, l2, l4) after ``tumble``: the landing foot at the nominal apex over the
        edge."""
        l1, l2, l3, l4 = tumble
        edge = (pts[l2] - pts[l1]) / np.linalg.norm(pts[l2] - pts[l1])
        out = np.array([edge[1], -edge[0]])  # to the right of l1 -> l2: away from l3
        landed = (pts[l1] + pts[l2]) / 2 + out * (self.config.stance_side * math.sqrt(3) / 2)
        return {l1: pts[l1], l2: pts[l2], l4: landed}

    def sweeps(self) -> dict:
        """How joint 1 of the planted limbs moves through each tumble, and where the landing limb's ends.

        Keys ``(tumble, landing)``, landing 0 or 1 for the landing limb's two knee-branch solutions (joint 1 half a
        turn apart); values ``(l1, l2, l3 sweeps, landed joint 1 in (-pi, pi])``, a sweep being (change from the
        start to the end stance, lowest and highest excursion on the way) in radians. Planned once per geometry from
        the nominal stance with joint 1 unbounded, so that the look-ahead can judge any winding: a planted limb
        cannot unwind joint 1 (its motion depends only on the feet, not on the turn it started at), and a limb kept
        planted through three tumbles winds it by 360 degrees.
        """
        if self._sweeps is not None:  # the look-ahead asks many times per decision: skip hashing the key
            return self._sweeps
        key = ("sweeps", self.polyhedron, self.links, self.config, self.foot_radius)
        if key not in _PLANNABLE:
            wide = np.array(self.joint_ranges)
            wide[0] = [-4 * np.pi, 4 * np.pi]
            planner = BeastPlanner(self.polyhedron, self.links, wide, self.foot_radius, self.config)
            table = {}
            for (l1, l2, l3), q in self._nominal_starts():
                tumble = (l1, l2, l3, self.landing_limb(l1, l2, l3))
                for landing in (0.0, math.pi):
                    tip = planner.tip_plan(
                        q, tumble, landing=self.stance_angles((l1, tumble[3], l2))[tumble[3]][0] + landing
                    )
                    if tip is None:
                        continue
                    stance = planner.stance_plan(tip.q[-1], (l1, l2, tumble[3]), (l3,))
                    theta1 = np.concatenate([tip.q, stance.q])[:, 0::3]
                    moves = []
                    for path in (theta1[:, l1], theta1[:, l2], tip.q[:, 3 * l3]):
                        rel = path - path[0]
                        moves.append((float(rel[-1]), float(rel.min()), float(rel.max())))
                    landed = float(np.mod(theta1[-1, tumble[3]] + np.pi, 2 * np.pi) - np.pi)
                    table[(tumble, int(landing > 0))] = (*moves, landed)
            _PLANNABLE[key] = table
        self._sweeps = _PLANNABLE[key]
        return self._sweeps

    def wind_on_paper(self, theta1: dict, tumble) -> list[dict]:
        """The planted limbs' joint 1 (by limb) after ``tumble`` on paper: one dict for each landing solution and
        turn that keeps every joint 1 in range (with a few degrees to spare for the feet's drift)."""
        l1, l2, l3, l4 = tumble
        low, high = self.joint_ranges[0] + np.radians([3.0, -3.0])
        out = []
        for landing in (0, 1):
            entry = self.sweeps().get((tuple(tumble), landing))
            if entry is None:
                continue
            *moves, landed = entry
            if not all(
                low <= theta1[limb] + lowest and theta1[limb] + highest <= high
                for limb, (_, lowest, highest) in zip((l1, l2, l3), moves, strict=True)
            ):
                continue
            after = {l1: theta1[l1] + moves[0][0], l2: theta1[l2] + moves[1][0]}
            for turns in (-1, 0, 1):
                if low <= landed + 2 * np.pi * turns <= high:
                    out.append({**after, l4: landed + 2 * np.pi * turns})
        return out

    def wind_now(self, q: np.ndarray, tumble) -> list[dict]:
        """As :meth:`wind_on_paper`, but for a tumble from the measured angles ``q``, planned for real: the first
        tumble from a stance off the nominal pattern (a task's start) sweeps joint 1 differently."""
        l1, l2, l3, l4 = tumble
        out = []
        for landing in (0, 1):
            entry = self.sweeps().get((tuple(tumble), landing))
            if entry is None:
                continue
            for turns in (-1, 0, 1):
                target = entry[-1] + 2 * np.pi * turns
                if not self.joint_ranges[0, 0] <= target <= self.joint_ranges[0, 1]:
                    continue
                tip = self.tip_plan(q, tumble, landing=target)
                stance = None if tip is None else self.stance_plan(tip.q[-1], (l1, l2, l4), (l3,))
                if stance is not None and abs(stance.q[-1][3 * l4] - target) < np.pi / 2:
                    out.append({limb: float(stance.q[-1][3 * limb]) for limb in (l1, l2, l4)})
        return out

    def _nominal_starts(self):
        """((l1, l2, l3), joint angles) for every tumble's start: a support face ordered by :meth:`order_edge`, in
        its nominal stance with the free limbs tucked."""
        for support in itertools.combinations(range(self.n_limbs), 3):
            if any(float(self.dirs[i] @ self.dirs[j]) < -0.99 for i, j in itertools.combinations(support, 2)):
                continue  # opposite limbs never stand together
            q = np.tile(TUCKED, (self.n_limbs, 1))
            for limb, angles in self.stance_angles(support).items():
                q[limb] = angles
            feet = self.feet(q.ravel())
            for c in support:
                a, b = (limb for limb in support if limb != c)
                yield self.order_edge(feet, a, b, c), q.ravel()

    def plannable(self) -> frozenset:
        """The tumbles (0-based) plannable from the nominal stance of their support, computed once per geometry."""
        key = (self.polyhedron, self.links, self.config, self.joint_ranges.tobytes(), self.foot_radius)
        if key not in _PLANNABLE:
            found = set()
            for (l1, l2, l3), q in self._nominal_starts():
                tumble = (l1, l2, l3, self.landing_limb(l1, l2, l3))
                if self.tip_plan(q, tumble) is not None:
                    found.add(tumble)
            _PLANNABLE[key] = frozenset(found)
        return _PLANNABLE[key]

    def ik_near(self, p_limb: np.ndarray, q_prev: np.ndarray) -> np.ndarray:
        """Knee-branch (theta3 > 0) inverse kinematics closest to ``q_prev`` (both (m, 3)); theta1 unwrapped."""
        sols = K.inverse_kinematics(p_limb[:, None, :], self.links, knee=1, flip=np.array([False, True]))
        diff = sols - q_prev[:, None, :]
        diff[..., 0] = np.mod(diff[..., 0] + np.pi, 2 * np.pi) - np.pi
        diff[..., 1] = np.mod(diff[..., 1] + np.pi, 2 * np.pi) - np.pi
        best = np.argmin(np.abs(diff).sum(axis=-1), axis=1)
        rows = np.arange(len(p_limb))
        return q_prev + diff[rows, best]

    def ik_nearest_any(self, p_limb: np.ndarray, q_prev: np.ndarray) -> np.ndarray:
        """Of all four closed-form solutions (both knee signs, both shoulder flips), the one nearest ``q_prev``,
        angles unwrapped onto it (both (m, 3))."""
        sols = K.ik_solutions(p_limb, self.links)
        diff = np.mod(sols - q_prev[:, None, :] + np.pi, 2 * np.pi) - np.pi
        best = np.argmin(np.abs(diff).sum(axis=-1), axis=1)
        return q_prev + diff[np.arange(len(p_limb)), best]

    def in_range(self, q: np.ndarray, margin: float = 0.0) -> bool:
        q = np.asarray(q).reshape(-1, self.n_limbs * 3)
        return bool(np.all(q >= self._low + margin) and np.all(q <= self._high - margin))

    # --------------------------------------------------------------------------------------------- planning
    def body_motion(
        self,
        q_now: np.ndarray,
        planted: list[int],
        feet_tumble: np.ndarray,
        pose0: tuple[np.ndarray, np.ndarray],
        pose1: tuple[np.ndarray, np.ndarray],
        free_targets: dict[int, np.ndarray],
        *,
        any_branch: bool = False,
        knots: int | None = None,
    ) -> JointTrajectory | None:
        """Joint trajectory moving the body from pose0 to pose1 (rotation body -> tumble, centre) with feet fixed.

        ``feet_tumble`` (n_limbs, 3) holds the planted feet in the tumble frame; the body's centre moves in a
        straight line and its orientation at a constant angular velocity (a constant twist split into translation
        and rotation, paper eq. 6-7), starting and ending at rest. Free limbs go in joint space
        from their current angles to ``free_targets``. The duration makes the fastest joint run at the configured
        rate. Planted limbs stay on the theta3 > 0 knee branch the tumbles need, or with ``any_branch`` follow the
        nearest of all four solutions (the crawl's legs, some of which stand with theta3 < 0 to keep joint 1 off
        its stop); then a foot must stay 1 mm inside its workspace and a jump between branches (a singularity
        crossed) is None. ``knots``: knot intervals (default the gait's).
        """
        key = _motion_key(q_now, planted, feet_tumble, pose0, pose1, free_targets, any_branch=any_branch, knots=knots)
        if key in self._motions:  # the same inputs plan the same motion: reuse it (trajectories are never modified)
            return self._motions[key]
        traj = self._body_motion(
            q_now, planted, feet_tumble, pose0, pose1, free_targets, any_branch=any_branch, knots=knots
        )
        if len(self._motions) >= MOTION_CACHE:
            del self._motions[next(iter(self._motions))]
        self._motions[key] = traj
        return traj

    def _body_motion(self, q_now, planted, feet_tumble, pose0, pose1, free_targets, *, any_branch, knots):
        """:meth:`body_motion`, planned."""
        q_now = np.asarray(q_now, dtype=float).reshape(self.n_limbs, 3)
        (r0, c0), (r1, c1) = pose0, pose1
        omega = rotation_log(r1 @ r0.T)  # spatial rotation vector, tumble frame
        dc = c1 - c0
        s_knots = np.linspace(0.0, 1.0, (self.config.knots if knots is None else knots) + 1)
        n = len(s_knots)
        q = np.repeat(q_now[None], n, axis=0)
        dq_ds = np.zeros_like(q)
        planted = list(planted)
        if planted:
            prev = q_now[planted]
            base = self.base[planted]
            for k, s in enumerate(s_knots):
                rot = rotation_exp(s * omega) @ r0
                centre = c0 + s * dc
                rel = feet_tumble[planted] - centre
                p_body = rel @ rot  # rot.T @ rel, row-wise
                p_limb = np.einsum("lji,lj->li", base, p_body)
                if not np.all(K.reachable(p_limb, self.links, tol=-1e-3 if any_branch else 1e-9)):
                    return None
                prev = self.ik_nearest_any(p_limb, prev) if any_branch else self.ik_near(p_limb, prev)
                q[k, planted] = prev
                # d(foot in body)/ds = -R^T (omega x (p - c) + dc); then into the limb frame, through J^-1.
                dp_body = -(np.cross(omega, rel) + dc) @ rot
                dp_limb = np.einsum("lji,lj->li", base, dp_body)
                jac = K.limb_jacobian(prev, self.links)
                dq_ds[k, planted] = np.stack(
                    [np.linalg.lstsq(jac[i], dp_limb[i], rcond=1e-6)[0] for i in range(len(planted))]
                )
            if any_branch and n > 1 and np.abs(np.diff(q[:, planted], axis=0)).max() > 0.6:
                return None
        for limb, target in free_targets.items():
            delta = np.asarray(target, dtype=float) - q_now[limb]
            q[:, limb] = q_now[limb] + s_knots[:, None] * delta
            dq_ds[:, limb] = delta
        # Time along the path: each knot interval takes as long as its fastest joint needs at the rate limit (the
        # robot slows where a limb nears a singularity instead of everywhere); the path starts and ends at rest,
        # so the end intervals get the cubic's 1.5x.
        dt = np.maximum(np.abs(np.diff(q, axis=0)).max(axis=(1, 2)) / self.rate, 1e-3)
        dt[[0, -1]] *= 1.5
        times = np.concatenate([[0.0], np.cumsum(dt)])
        ds = np.diff(s_knots)
        s_dot = np.zeros(n)
        s_dot[1:-1] = np.minimum(ds[:-1] / dt[:-1], ds[1:] / dt[1:])
        qd = dq_ds * s_dot[:, None, None]
        return JointTrajectory(times, q.reshape(n, -1), qd.reshape(n, -1))

    def tip_plan(
        self,
        q_now: np.ndarray,
        tumble: tuple[int, int, int, int],
        extra: float = 0.0,
        future=(),
        landing: int | None = None,
    ):
        """The tip plan of the configured keyframe, or of the first alternative keyframe that is plannable.
        ``landing`` (radians) asks for the landing limb's foothold solution whose joint 1 is nearest it."""
        cfg = self.config
        for keyframe in ((cfg.tip_centre, cfg.tip_rotation_deg, cfg.roll_deg), *cfg.tip_alternatives):
            traj = self._tip_plan(q_now, tumble, keyframe, extra, future, landing)
            if traj is not None:
                return traj
        return None

    def _tip_plan(self, q_now, tumble, keyframe, extra, future, landing):
        """Trajectory K0 -> K1 of tumble (l1, l2, l3, l4) (0-based limbs) from the measured angles, or None.

        ``keyframe`` is (tip_centre, tip_rotation_deg, roll_deg), as in :class:`GaitConfig`. ``extra`` pushes the tip
        keyframe that much further forward (a retry when the body did not tip). None when a joint would leave its
        range or a foot its workspace, here or in the stance after landing. ``future`` lists the tumbles planned
        after this one: the landing limb's branch (of its two knee-branch solutions) is the one from which they stay
        plannable too, since a planted limb cannot change branch until it is lifted.
        """
        cfg = self.config
        tip_centre, tip_rotation_deg, roll_deg = keyframe
        l1, l2, l3, l4 = tumble
        feet = self.feet(q_now)
        rot0, origin = self.tumble_frame(feet, l1, l2, l3)
        c0 = -rot0 @ origin
        feet_t = (feet - origin) @ rot0.T
        a, b, c = np.radians(tip_rotation_deg)
        r_k0 = self.stance_orientation(l1, l2, l3)
        r1 = K.rot_y(a) @ K.rot_x(b) @ K.rot_z(c) @ r_k0
        c1 = np.array(tip_centre) + np.array([extra, 0.0, 0.0])
        # Landing foothold: the apex of the nominal triangle on the edge, on the ground (foot l3 mirrored across the
        # edge when the feet are on the nominal pattern; a pattern that has spread or shrunk returns to it within
        # two tumbles), rolled back by the free roll's angle.
        land = np.array([cfg.stance_side * math.sqrt(3) / 2, (feet_t[l1, 1] + feet_t[l2, 1]) / 2, self.foot_radius])
        alpha = math.radians(roll_deg)
        pre = land.copy()
        pre[0], pre[2] = (
            land[0] * math.cos(alpha) - (land[2] - self.foot_radius) * math.sin(alpha),
            self.foot_radius + land[0] * math.sin(alpha) + (land[2] - self.foot_radius) * math.cos(alpha),
        )
        p_body = r1.T @ (pre - c1)
        p_limb = self.base[l4].T @ p_body
        if not K.reachable(p_limb, self.links):
            return None
        # The landing limb's knee-branch solutions with joint 1 at every turn within its range, the one nearest its
        # nominal stance after landing first (or only the one asked for).
        near = self.ik_near(p_limb[None], self.stance_angles((l1, l4, l2))[l4][None])[0]
        options = []
        for sol in K.inverse_kinematics(p_limb[None], self.links, knee=1, flip=np.array([False, True])):
            q_pre = near + np.mod(sol - near + np.pi, 2 * np.pi) - np.pi
            for turns in (-1, 0, 1):
                shifted = q_pre + [2 * np.pi * turns, 0.0, 0.0]
                if self.joint_ranges[0, 0] <= shifted[0] <= self.joint_ranges[0, 1]:
                    options.append(shifted)
        if landing is not None:
            options = sorted(options, key=lambda q: abs(q[0] - landing))[:1]
        else:
            options.sort(key=lambda q: float(np.abs(q - near).sum()))
        free = {limb: TUCKED for limb in range(self.n_limbs) if limb not in tumble}
        for q_pre in options:
            free[l4] = q_pre
            traj = self.body_motion(q_now, [l1, l2, l3], feet_t, (rot0, c0), (r1, c1), free)
            if traj is None or not self.in_range(traj.q):
                continue
            # The stance after landing must be plannable too. The joints hold through the free roll, so the landed
            # robot has K1's joint angles and the stance plan from there is exactly the one that will run (this is
            # what leaves 4 of the 4-beast's 12 tumbles unplannable: joint 1 would have to pass +-180 degrees).
            stance = self.stance_plan(traj.q[-1], (l1, l2, l4), (l3,))
            if stance is None:
                continue
            if future and self.tip_plan(stance.q[-1], future[0], future=future[1:]) is None:
                continue
            return traj
        return None

    def stance_plan(self, q_now: np.ndarray, support: tuple[int, int, int], lifted: tuple[int, ...]):
        """Trajectory to the nominal stance over the measured ``support`` feet; ``lifted`` limbs fold up. Or None."""
        feet = self.feet(q_now)
        l1, l2, l3 = self.order_edge(feet, *support)
        rot0, origin = self.tumble_frame(feet, l1, l2, l3)
        c0 = -rot0 @ origin
        feet_t = (feet - origin) @ rot0.T
        nominal, _ = self.nominal_feet(l1, l2, l3)
        measured = feet[[l1, l2, l3]]
        # Kabsch: the body pose (in the current body frame) whose nominal feet best fit the measured ones.
        rk, tk = kabsch(nominal, measured)
        r1 = rot0 @ rk
        c1 = rot0 @ (tk - origin)
        free = {limb: TUCKED for limb in range(self.n_limbs) if limb not in (l1, l2, l3)}
        traj = self.body_motion(q_now, [l1, l2, l3], feet_t, (rot0, c0), (r1, c1), free)
        return traj if traj is not None and self.in_range(traj.q) else None
