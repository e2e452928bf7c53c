"""The rolling gait of the Platonic beasts (paper section 4), planned from the robot's own sensors.

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots", sections 3 and 4
(``../shared/seeds/002_*.txt``); the working tumble of the spec's feasibility study (``../shared/spec/beast.md``,
appendix) is the starting point for the keyframes.

A tumble (l1 l2 l3 l4) tips the body over the edge of feet l1, l2: l3 starts planted and ends free, l4 lands. Each
tumble is planned afresh from the measured state (the spherical feet roll about 20 mm per tumble, so a plan made once
drifts off the ground within a few tumbles):

1. **Feet from the encoders.** Forward kinematics of the joint angles puts every foot in the body frame; the three
   planted ones (the contact switches say which) give the ground plane and the **tumble frame**: origin on the ground
   under the midpoint of the tipping edge, y from foot l1 to foot l2, z up (the paper's ground frame z = y x (p3 - p1),
   which points to the body exactly for the right ordering), x = y x z forward, away from foot l3. The body's pose in
   that frame follows, so no privileged pose is needed.
2. **Tip (K0 -> K1).** The body translates along the tumble x axis while rotating about an axis parallel to y
   (section 4.1; a small yaw and sideways shift from the feasibility study keep every limb inside its workspace),
   until the centre of mass is a few millimetres past the edge. The planted feet stay put: at each knot every planted
   limb's joint angles come from the closed-form inverse kinematics on the theta3 > 0 knee branch, continuous from the
   previous knot, and its joint velocities from the limb Jacobian (J theta_dot = d p / dt, section 4.2), giving a
   piecewise cubic (Hermite) joint trajectory, each knot interval timed so that its fastest joint runs at the
   configured rate. Meanwhile the free limb swings over the top in joint space to a foothold placed so that it lands
   at the apex of the nominal triangle on the edge (foot l3 mirrored, on the nominal pattern) after a free roll.
3. **Roll.** The targets hold while gravity tips the body about the edge (the paper's brief dynamic tip: two feet down
   for well under a second) until the contact switches report the landed foot down and the lifted one free. If the
   body has not tipped after a second the tip keyframe is pushed a few millimetres further; if nothing lands within
   ``ROLL_TIMEOUT`` the robot stands on whatever feet are down and goes on from there.
4. **Stance (landed -> K3).** The feet are measured again and the body moves (same planted-limb machinery) to the
   nominal stance over the new support triangle, found by fitting the nominal feet pattern to the measured feet
   (Kabsch), while the lifted limb folds straight up over the top. The next tumble starts from there.

The same plan serves every tumble by relabelling limbs, and every polyhedron: a support triangle of the 6-beast is a
face of the octahedron of its feet, the tumble lands the limb opposite the lifted one, and the stance's "up" is minus
the sum of the support limbs' axes. Which edge to tip over comes from a heading carried across tumbles in a frame
attached to planted feet (the robot cannot see the world's axes) and a short look-ahead that rolls the support
triangle on paper, never straight back unless allowed. A planted limb cannot unwind joint 1: each tumble it tips over
turns it by the same amount (120 degrees on the 4-beast), so the look-ahead follows every planted limb's joint 1 with
each tumble's sweep (planned once from the nominal stance; the first tumble from the measured angles) and keeps it in
range, choosing where the landing limb's joint 1 starts (either knee-branch solution, at any turn in range). With
joint 1 within +-180 degrees this leaves the 4-beast one strip, the feasibility study's (1234)(4213)(4321)(1342)
(8 of its 12 tumbles are plannable from the nominal stance); a limb planted through a third tumble, which a turn
needs, winds joint 1 by 360 degrees. The landing limb's branch is the one from which the next two tumbles of the
look-ahead's path stay plannable.

Public names: :class:`RollingGaitController` (the closed-loop state machine for one environment),
:class:`RightingController` (stand up from any orientation); the planner is :mod:`baselines.beast.planner`.
"""

from __future__ import annotations

import itertools

import numpy as np

from baselines.beast.geometry import unit
from baselines.beast.observation import split_observation
from baselines.beast.planner import TUCKED, BeastPlanner, JointTrajectory
from polyenvs.beast.model import CONTROL_DT
from polyenvs.beast.sensors import TILT_AXES

__all__ = ["RightingController", "RollingGaitController"]

#: Seconds to wait for a landing after the tip before standing on whatever feet are down and going on.
ROLL_TIMEOUT = 4.0
#: Tumbles the look-ahead plans ahead when choosing the next one.
LOOKAHEAD = 4
#: Tumbles after the next one that the landing limb's branch is chosen for.
FUTURE = 2


class RollingGaitController:
    """Closed-loop rolling gait for one environment: observation in, joint-target action out, plan kept inside.

    ``first_tumble`` (1-based) is taken when its first three limbs are the measured support (by default: over the
    edge of the two lowest-numbered support limbs, which is (1 2 3 4) for the 4-beast);
    ``heading`` (tumble frame of the first tumble) defaults to the 4-beast's straight strip, 30 degrees left of the
    first tip; ``pivot`` (1-based) keeps that limb planted: every tumble tips over an edge containing it, the sharp
    turn of the paper's Figures 10 and 11; ``allow_back`` lets the look-ahead tip back over the last edge (the
    4-beast changes strips that way, since within +-180 degrees of joint 1 each strip's next tumble is forced).
    """

    def __init__(
        self,
        planner: BeastPlanner,
        *,
        first_tumble: tuple[int, int, int, int] | None = None,
        max_tumbles: int | None = None,
        heading: np.ndarray | None = None,
        pivot: int | None = None,
        disabled_limbs=(),
        allow_back: bool = False,
    ):
        self.planner = planner
        self.allow_back = allow_back
        self.disabled = frozenset(int(v) - 1 for v in disabled_limbs)
        self.pivot = None if pivot is None else int(pivot) - 1
        self.first_tumble = None if first_tumble is None else tuple(int(v) - 1 for v in first_tumble)
        self.max_tumbles = max_tumbles
        self.heading_first = heading
        self.phase = "start"
        self.traj: JointTrajectory | None = None
        self.t = 0.0
        self.tumble: tuple[int, ...] | None = None
        self.landing: float | None = None  # the landing limb's joint 1 that the look-ahead planned for
        self.future: tuple = ()
        self.support: tuple[int, ...] | None = None
        self.tumbles_done = 0
        self.hold_q: np.ndarray | None = None
        self.landed_for = 0.0
        self.waited = 0.0
        self.nudges = 0
        self.heading_edge: tuple[int, int] | None = None
        self.heading_vec: np.ndarray | None = None
        self.last_edge: frozenset | None = None
        self.history: list[tuple[int, ...]] = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        sensors = split_observation(obs)
        q = sensors["joint_pos"]
        contact = sensors["foot_contact"] > 0.5
        if self.phase == "start":
            self._stand_on_feet_down(q, contact)
        elif self.phase in ("tip", "stance"):
            self._follow_plan(q)
        elif self.phase == "roll":
            self._wait_for_landing(q, contact)
        elif self.phase == "stuck":
            # Try again from whatever stands now, a few times a second (the feet may have settled differently).
            self.waited += CONTROL_DT
            if self.waited >= 1.0:
                self._resume(q, contact)
        if self.traj is not None and self.phase in ("tip", "stance"):
            return self.planner.to_action(self.traj(self.t))
        return self.planner.to_action(self.hold_q)

    def _stand_on_feet_down(self, q: np.ndarray, contact: np.ndarray):
        """Phase "start": hold the measured angles and, once three feet are down, plan the first tumble."""
        self.hold_q = q.copy()
        down = tuple(int(i) for i in np.flatnonzero(contact))
        if len(down) >= 3:
            self.support = self._face(down)
            self._begin_next(q)

    def _follow_plan(self, q: np.ndarray):
        """Phases "tip" and "stance": advance along the plan; at its end, wait for the landing after a tip, or go
        on to the next tumble after a stance move."""
        self.t += CONTROL_DT
        if self.t >= self.traj.duration:
            self.hold_q = self.traj.q[-1].copy()
            if self.phase == "tip":
                self.phase, self.landed_for, self.waited = "roll", 0.0, 0.0
            else:
                self._begin_next(q)

    def _wait_for_landing(self, q: np.ndarray, contact: np.ndarray):
        """Phase "roll": the landing foot down (and the lifted one up) for 0.3 s lands the tumble; a tip that has not
        gone over after a second is nudged further; after ``ROLL_TIMEOUT`` the gait goes on from what stands."""
        _, _, l3, l4 = self.tumble
        self.waited += CONTROL_DT
        landed = contact[l4] and not contact[l3]
        self.landed_for = self.landed_for + CONTROL_DT if landed else 0.0
        if self.landed_for >= 0.3:
            self._land(q)
        elif self.waited >= 1.0 and contact[l3] and not contact[l4] and self.nudges < self.planner.config.max_nudges:
            self.nudges += 1
            extra = self.nudges * self.planner.config.nudge
            plan, self.future = self._tip_plan(q, self.tumble, self.future, self.landing, extra)
            if plan is not None:
                self._start(plan, "tip")
        elif self.waited >= ROLL_TIMEOUT:
            self._resume(q, contact)

    def _land(self, q: np.ndarray):
        """Count the tumble, stand on its new support and plan the stance move that lifts the old foot."""
        l1, l2, l3, l4 = self.tumble
        self.tumbles_done += 1
        self.history.append(tuple(v + 1 for v in self.tumble))
        self.support = (l1, l2, l4)
        self.last_edge = frozenset((l1, l2))
        plan = self.planner.stance_plan(q, self.support, (l3,))
        if plan is None:
            self.phase, self.waited = "stuck", 0.0
        else:
            self._start(plan, "stance")

    def _face(self, down) -> tuple[int, ...] | None:
        """Three of the feet that are down forming a support face (no two opposite limbs), working limbs first."""
        dirs = self.planner.dirs
        faces = [
            f
            for f in itertools.combinations(down, 3)
            if all(float(dirs[i] @ dirs[j]) > -0.99 for i, j in itertools.combinations(f, 2))
        ]
        faces.sort(key=lambda f: len(self.disabled & set(f)))
        return faces[0] if faces else None

    def _resume(self, q: np.ndarray, contact: np.ndarray):
        """After a tumble that did not land as planned, or when stuck: stand on the feet that are down and go on."""
        self.waited = 0.0
        support = self._face(tuple(int(i) for i in np.flatnonzero(contact)))
        if support is None:
            self.phase = "stuck"
            return
        self.support, self.last_edge = support, None
        lifted = tuple(limb for limb in range(self.planner.n_limbs) if limb not in support)
        plan = self.planner.stance_plan(q, support, lifted)
        if plan is None:
            self.phase = "stuck"
        else:
            self._start(plan, "stance")

    def _start(self, traj: JointTrajectory, phase: str):
        self.traj, self.t, self.phase = traj, 0.0, phase

    def _begin_next(self, q: np.ndarray):
        """Choose and plan the next tumble from the current support, or hold when done or nothing is feasible."""
        if self.max_tumbles is not None and self.tumbles_done >= self.max_tumbles:
            self.phase = "done"
            return
        p = self.planner
        feet = p.feet(q)
        for tumble, landing, future in self._candidates(feet, q):
            plan, future = self._tip_plan(q, tumble, future[:FUTURE], landing)
            if plan is not None:
                self._carry_heading(feet, tumble)
                self.tumble, self.landing, self.future, self.nudges = tumble, landing, future, 0
                self._start(plan, "tip")
                return
        # A pivot turn ends where no tumble about the pivot is plannable; otherwise nothing is, which is stuck.
        self.phase = "done" if self.pivot is not None else "stuck"

    def _tip_plan(self, q: np.ndarray, tumble, future: tuple, landing: float, extra: float = 0.0) -> tuple:
        """(tip plan, the part of ``future`` it keeps plannable): the landing foothold the look-ahead chose, checked
        for as much of its path as can be planned, down to none (a nudged tip may leave no room for the path); then
        any foothold."""
        for target in (landing, None):
            for depth in range(len(future), -1, -1):
                plan = self.planner.tip_plan(q, tumble, extra=extra, future=future[:depth], landing=target)
                if plan is not None:
                    return plan, future[:depth]
        return None, future

    def _heading_body(self, feet: np.ndarray) -> np.ndarray:
        """The carried heading in the body frame, from the feet that anchor it."""
        return self._edge_frame(feet, *self.heading_edge).T @ self.heading_vec

    def _edge_frame(self, feet: np.ndarray, a: int, b: int) -> np.ndarray:
        """Body -> ground rotation anchored on planted feet a, b: y from a to b, z up (the support's normal)."""
        s = self.support
        z = unit(np.cross(feet[s[1]] - feet[s[0]], feet[s[2]] - feet[s[0]]))
        z = z if np.dot(z, -feet[s[0]]) > 0 else -z
        y = feet[b] - feet[a]
        y = unit(y - np.dot(y, z) * z)
        return np.stack([np.cross(y, z), y, z])

    def _carry_heading(self, feet, tumble):
        l1, l2, l3, _ = tumble
        rot = self._edge_frame(feet, l1, l2)
        h = rot @ self._heading_body(feet)
        h[2] = 0.0
        self.heading_vec, self.heading_edge = unit(h), (l1, l2)

    def _candidates(self, feet, q) -> list[tuple[tuple[int, int, int, int], float, tuple]]:
        """Tumbles from the current support, best first, each with the landing limb's joint 1 and the look-ahead's
        best path after it.

        The look-ahead rolls the support triangle on paper (each landing foot at the nominal apex over the tipping
        edge) through ``LOOKAHEAD`` tumbles whose joint-1 sweeps (:meth:`BeastPlanner.sweeps`) keep every planted
        limb in range as it winds, from the measured angles ``q``, and that keep disabled limbs off the ground,
        never straight back, and scores a first tumble by the best final advance along the heading; a branch that
        runs into a dead end scores a metre less for every tumble it falls short. With ``pivot`` every tumble keeps
        that limb planted.
        """
        p = self.planner
        s = self.support
        if self.tumbles_done == 0 and self.heading_vec is None:
            # The heading starts in the frame of the default first tumble: over the edge of the two lowest-numbered
            # support limbs, lifting the highest (the canonical (1234) of the 4-beast; along +x in the tasks).
            a, b, c = sorted(s)
            l1, l2, _ = p.order_edge(feet, a, b, c)
            self.heading_edge, self.heading_vec = (l1, l2), self._default_heading()
        rot = self._edge_frame(feet, s[0], s[1])
        h = (rot @ self._heading_body(feet))[:2]
        if self.tumbles_done == 0:
            a, b, c = sorted(s)
            l1, l2, l3 = p.order_edge(feet, a, b, c)
            if self.first_tumble is not None and set(self.first_tumble[:3]) == set(s):
                options = [self.first_tumble]
            elif not self.disabled:
                options = [(l1, l2, l3, p.landing_limb(l1, l2, l3))]
            else:
                # A disabled limb standing in the support is lifted first, and none ever lands (paper section 5:
                # reorient so that the defective limb is on top); otherwise the look-ahead picks the first tumble.
                pts = {limb: (rot @ feet[limb])[:2] for limb in s}
                options = self._options(pts, None)
                lift = [t for t in options if t[2] in self.disabled]
                options = lift or options
        else:
            options = self._options({limb: (rot @ feet[limb])[:2] for limb in s}, self.last_edge)
        pts = {limb: (rot @ feet[limb])[:2] for limb in s}
        scored = []
        for t in options:
            rolled = p.roll_on_paper(pts, t)
            outcomes = p.wind_now(q, t)
            if not outcomes:  # tried last: the planner itself is the judge
                scored.append((-np.inf, t, None, ()))
            for wound in outcomes:
                score, path = self._lookahead(rolled, wound, frozenset(t[:2]), LOOKAHEAD - 1, h)
                scored.append((score, t, wound[t[3]], path))
        scored.sort(key=lambda item: -item[0])
        return [(t, landing, path) for _, t, landing, path in scored]

    def _default_heading(self) -> np.ndarray:
        """The heading in the first tumble's frame: the 4-beast's straight strip runs 30 degrees to the left of the
        first tip; the other beasts keep rolling the first tumble's way."""
        if self.heading_first is not None:
            return np.asarray(self.heading_first, dtype=float)
        return np.array([0.866, 0.5, 0.0]) if self.planner.n_limbs == 4 else np.array([1.0, 0.0, 0.0])

    def _options(self, pts: dict, last_edge) -> list[tuple[int, int, int, int]]:
        """The tumbles from a support on paper (ground points by planted limb) worth looking at."""
        p = self.planner
        out = []
        for c in pts:
            a, b = (limb for limb in pts if limb != c)
            back = frozenset((a, b)) == last_edge and (not self.allow_back or self.pivot is not None)
            if back or (self.pivot is not None and self.pivot not in (a, b)):
                continue
            e, f = pts[b] - pts[a], pts[c] - pts[a]
            l1, l2 = (a, b) if e[0] * f[1] - e[1] * f[0] > 0 else (b, a)
            t = (l1, l2, c, p.landing_limb(l1, l2, c))
            if t[3] not in self.disabled:
                out.append(t)
        return out

    def _lookahead(self, pts: dict, theta1: dict, last_edge, depth: int, h: np.ndarray) -> tuple[float, tuple]:
        """(best advance along h after ``depth`` more tumbles, the path of tumbles that reaches it)."""
        here = float(np.mean(list(pts.values()), axis=0) @ h)
        if depth == 0:
            return here, ()
        best = (here - float(depth), ())  # a dead end: a metre less for every tumble it cuts short
        for t in self._options(pts, last_edge):
            rolled = self.planner.roll_on_paper(pts, t)
            for wound in self.planner.wind_on_paper(theta1, t):
                score, path = self._lookahead(rolled, wound, frozenset(t[:2]), depth - 1, h)
                if score > best[0] or not best[1]:
                    best = (score, (t, *path))
        return best


class RightingController:
    """Righting from any orientation: stand on the three limbs that point most nearly down, as the tilt bits say.

    Gravity's direction in the body frame is the mean axis of the switches that read "below horizontal"; the support
    is the feasible triple (any three limbs of the 4-beast, one limb of each opposite pair of the 6-beast) whose axes
    point most nearly down. Those limbs swing in joint space to their nominal stance and the others fold up; after a
    short settle the contact switches decide: the three feet down (and no other) is a stance, otherwise it reads the
    tilt again and tries the next triple. With ``roll_after`` the rolling gait takes over from the stance.
    """

    def __init__(self, planner: BeastPlanner, roll_after: bool = False, settle: float = 0.5):
        self.planner = planner
        self.tilt_axes = TILT_AXES
        self.roll_after = roll_after
        self.settle = settle
        self.phase = "start"
        self.traj: JointTrajectory | None = None
        self.t = 0.0
        self.waited = 0.0
        self.support: tuple[int, ...] | None = None
        self.tried: list[tuple[int, ...]] = []
        self.gait: RollingGaitController | None = None
        n = planner.n_limbs
        dirs = planner.dirs
        # Candidate supports: triples whose limbs are pairwise non-opposite (a face of the limbs' polyhedron).
        self.triples = [
            t
            for t in itertools.combinations(range(n), 3)
            if all(float(dirs[i] @ dirs[j]) > -0.99 for i, j in itertools.combinations(t, 2))
        ]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        p = self.planner
        if self.gait is not None:
            return self.gait(obs)
        sensors = split_observation(obs)
        q = sensors["joint_pos"]
        contact = sensors["foot_contact"] > 0.5
        if self.phase == "start":
            # Let a thrown robot land and settle first: the tilt switches only say where "down" is at rest.
            self.waited += CONTROL_DT
            if self.waited >= self.settle:
                self._plan(q, sensors["tilt"])
        elif self.phase == "move":
            self.t += CONTROL_DT
            if self.t >= self.traj.duration:
                self.phase, self.waited = "settle", 0.0
        elif self.phase == "settle":
            self.waited += CONTROL_DT
            if self.waited >= self.settle:
                down = set(np.flatnonzero(contact).tolist())
                if down == set(self.support):
                    self.phase = "stood"
                    if self.roll_after:
                        self.gait = RollingGaitController(p)
                        return self.gait(obs)
                else:
                    self._plan(q, sensors["tilt"])
        return p.to_action(self.traj(self.t) if self.traj is not None else q)

    def _plan(self, q: np.ndarray, tilt: np.ndarray):
        p = self.planner
        on = tilt > 0.5
        # A switch that reads 1 points below the horizontal, so gravity lies along their mean axis.
        down = self.tilt_axes[on].mean(axis=0) if on.any() else np.zeros(3)
        scores = [float(p.dirs[list(t)].sum(axis=0) @ down) for t in self.triples]
        order = [self.triples[i] for i in np.argsort(scores)[::-1]]
        fresh = [t for t in order if t not in self.tried[-2:]]
        self.support = (fresh or order)[0]
        self.tried.append(self.support)
        target = q.reshape(p.n_limbs, 3).copy()
        for limb in range(p.n_limbs):
            target[limb] = TUCKED
        for limb, angles in p.stance_angles(self.support).items():
            target[limb] = angles
        target = target.ravel()
        duration = max(0.3, 1.5 * float(np.abs(target - q).max()) / p.rate)
        times = np.array([0.0, duration])
        self.traj = JointTrajectory(times, np.stack([q, target]), np.zeros((2, len(q))))
        self.t, self.phase = 0.0, "move"
