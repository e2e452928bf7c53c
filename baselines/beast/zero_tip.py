"""The zero-tip tumble of the 4-beast (paper section 3): a tumble that never stands on fewer than three feet.

Paper: Pai, Barman and Ralph, "Platonic Beasts", section 3: "In the general case there is a brief dynamic "tip"
episode during which only two limbs are in contact with the ground. For the choice of kinematic parameters of our
prototype, all four limbs can simultaneously contact the ground, and thus the duration of the tip episode can be
reduced to zero. Such a zero tip gait will be slower, but will minimize the impact loads on the limb. Note that the
zero tip gait is a creeping gait for the 4-beast in that at most one limb is off the ground at any time."

A zero-tip tumble (l1 l2 l3 l4) replaces the rolling gait's tip and free roll (:mod:`baselines.beast.gait`) by four
statically stable moves, planned together from the measured state in the same tumble frame (origin under the
middle of edge l1-l2, x away from foot l3, z up):

1. ``reach``: on feet l1, l2, l3 the body tilts forward to a pose A whose centre of mass is still ``MARGIN`` inside
   the support triangle, while limb l4 swings over the top to ``HOVER`` above its foothold;
2. ``touch``: limb l4 sets its foot down on the foothold, on the floor and not into it (a foot pressed in puts the
   four feet off one plane, and the body rocks on the diagonal of feet l3 and l4);
3. ``shift``: on all four feet the body moves to a pose B whose centre of mass is ``MARGIN`` inside the new triangle
   l1, l2, l4 (the paper's four-feet-down configuration, geometry check B3);
4. ``lift``: limb l3 lifts its foot ``HOVER`` straight up.

The rolling gait's stance move then folds l3 over the top and centres the body on the new triangle. A and B come
from a grid of body poses (tilt about the edge's axis, forward position, height) on which every limb reaches its
foot on the knee branch within its joint range, the body and the knees clear the floor, and the centre of mass
(from the encoder angles and the model's masses, :func:`baselines.beast.crawl.centre_of_mass`) has the margin; of
those, the pair nearest each other whose moves are plannable.

With Table 1's limbs and our joint-2 limit of 160 degrees, the four feet cannot be down at once with the landing foot
at the rolling gait's 260 mm from the edge (no grid pose), so the foothold comes closer: 200 mm from the start
stance (at 220 mm no pose has the margin in both triangles). A MuJoCo run of the canonical tumble (seeds 0-4, -v0 and -v1) never has fewer than three feet on the floor,
advances the body 158-161 mm, takes 33.1-33.3 s at 20 deg/s (the rolling gait: 15.6 s) and loads no foot above 0.45
body weights (the rolling gait's landing: 1.56). Only that first tumble of the strip is possible, though: the
landing limb stands in every four-feet pose found on its solution with joint 1 at +60 degrees, not the strip's -120
(on that one joint 2 would pass 160 degrees before the centre of mass crosses the edge), and from +60 the strip's
next tumble (4213) would wind its joint 1 to 300 degrees; the other (1423) is not plannable either, so the
controller then holds (``docs/papers/beasts.md``).
"""

from __future__ import annotations

import math

import numpy as np

from baselines.beast.crawl import centre_of_mass, leg_trajectory
from baselines.beast.gait import RollingGaitController
from baselines.beast.planner import BeastPlanner, JointTrajectory
from polyenvs.beast import kinematics as K

__all__ = ["ZeroTipController", "four_feet_poses", "zero_tip_plan"]

#: Body tilts (about the tipping edge, from the start stance's orientation, degrees), forward positions and heights
#: (m, tumble frame) searched for the four-feet poses.
TILTS_DEG = np.arange(16.0, 80.0, 2.0)
FORWARD = np.arange(-0.08, 0.0801, 0.005)
HEIGHTS = np.arange(0.10, 0.1801, 0.005)
#: Distances of the landing foothold from the tipping edge tried, nearest the rolling gait's apex first (m).
FOOTHOLDS = (0.24, 0.22, 0.20, 0.18)
#: Least distance of the centre of mass inside the support triangle in poses A and B (m): with 20 mm the body
#: reached B only 4 mm past the edge in MuJoCo (the feet roll and the servos give) and rocked when l3 lifted.
MARGIN = 0.03
#: Height of a foot above its foothold before it touches down and after it lifts (m).
HOVER = 0.04
#: Least heights above the floor of the body centre (its circumsphere, of radius 120 mm, 10 mm clear) and of the
#: knees (the links' 12 mm capsules 10 mm clear), m.
BODY_CLEARANCE = K.BODY_SIDE / math.sqrt(2) + 0.01
KNEE_CLEARANCE = 0.022


def _grid(r0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, 3, 3) and centres (N, 3) of the searched poses: ``r0`` tilted about y, then placed."""
    tilt, x, z = np.meshgrid(np.radians(TILTS_DEG), FORWARD, HEIGHTS, indexing="ij")
    tilt, x, z = tilt.ravel(), x.ravel(), z.ravel()
    c, s = np.cos(tilt), np.sin(tilt)
    rot_y = np.zeros((len(tilt), 3, 3))
    rot_y[:, 0, 0], rot_y[:, 0, 2], rot_y[:, 1, 1], rot_y[:, 2, 0], rot_y[:, 2, 2] = c, s, 1.0, -s, c
    return rot_y @ r0, np.stack([x, np.zeros_like(x), z], axis=1)


def _inside(points: np.ndarray, triangle: np.ndarray) -> np.ndarray:
    """Signed distances (N,) of ground points (N, 2) inside a triangle (3, 2): positive inside, the nearest edge's."""
    out = np.full(len(points), np.inf)
    for i in range(3):
        a, b, other = triangle[i], triangle[(i + 1) % 3], triangle[(i + 2) % 3]
        normal = np.array([a[1] - b[1], b[0] - a[0]]) / np.linalg.norm(b - a)
        normal = normal if normal @ (other - a) > 0 else -normal
        out = np.minimum(out, (points - a) @ normal)
    return out


def _nearest_solutions(planner: BeastPlanner, p_limb: np.ndarray, reference: np.ndarray):
    """Per pose and limb (``p_limb`` (N, limbs, 3) limb-frame feet), the knee-branch solution within the joint
    ranges nearest ``reference`` (limbs, 3): (solutions (N, limbs, 3), whether every limb has one (N,))."""
    sols = K.inverse_kinematics(p_limb[:, :, None], planner.links, knee=1, flip=np.array([False, True]))
    gap = np.abs(np.mod(sols - reference[None, :, None] + np.pi, 2 * np.pi) - np.pi).sum(axis=-1)
    fits = np.all((sols >= planner.joint_ranges[:, 0]) & (sols <= planner.joint_ranges[:, 1]), axis=-1)
    gap = np.where(fits, gap, np.inf)
    pick = np.argmin(gap, axis=-1)[..., None]
    found = np.isfinite(np.take_along_axis(gap, pick, axis=-1)[..., 0]).all(axis=1)
    return np.take_along_axis(sols, pick[..., None], axis=2)[:, :, 0], found


def four_feet_poses(planner: BeastPlanner, ground: np.ndarray, tumble, reference: np.ndarray):
    """The grid poses on which all four feet stand on ``ground`` (n_limbs, 3; tumble frame, sphere centres):
    (rotations, centres, joint angles (N, n_joints), margin of the centre of mass inside triangle l1 l2 l3, and
    inside l1 l2 l4). Each limb takes the knee-branch solution nearest ``reference`` (n_joints,)."""
    l1, l2, l3, l4 = limbs = list(tumble)
    rot, centre = _grid(planner.stance_orientation(l1, l2, l3))
    rel = ground[limbs][None] - centre[:, None]  # (N, 4, 3)
    p_limb = np.einsum("lji,nkj,nlk->nli", planner.base[limbs], rot, rel)  # base^T rot^T (foot - centre)
    ok = K.reachable(p_limb, planner.links).all(axis=1) & (centre[:, 2] >= BODY_CLEARANCE)
    rot, centre = rot[ok], centre[ok]
    angles, ok = _nearest_solutions(planner, p_limb[ok], reference.reshape(planner.n_limbs, 3)[limbs])
    knees = np.einsum("nij,ljk,nlk->nli", rot, planner.base[limbs], K.dh_frames(angles, planner.links)[..., 1, :3, 3])
    ok &= (knees[..., 2] + centre[:, None, 2]).min(axis=1) >= KNEE_CLEARANCE
    q = np.repeat(reference.reshape(1, planner.n_limbs, 3), int(ok.sum()), axis=0)
    q[:, limbs] = angles[ok]
    q = q.reshape(len(q), planner.n_limbs * 3)
    rot, centre = rot[ok], centre[ok]
    com = np.array([r @ centre_of_mass(planner, qi) + c for r, c, qi in zip(rot, centre, q, strict=True)])
    com = com.reshape(len(q), 3)[:, :2]
    return rot, centre, q, _inside(com, ground[[l1, l2, l3], :2]), _inside(com, ground[[l1, l2, l4], :2])


def _concatenate(parts: list[JointTrajectory]) -> JointTrajectory:
    """One trajectory through the knots of moves that each start and end at rest, one after the other."""
    times, q, qd, offset = [parts[0].times[:1]], [parts[0].q[:1]], [parts[0].qd[:1]], 0.0
    for part in parts:
        times.append(part.times[1:] + offset)
        q.append(part.q[1:])
        qd.append(part.qd[1:])
        offset += part.duration
    return JointTrajectory(np.concatenate(times), np.concatenate(q), np.concatenate(qd))


def zero_tip_plan(planner: BeastPlanner, q_now: np.ndarray, tumble, landing: float | None = None):
    """The zero-tip tumble's moves (reach, touch, shift, lift) as one joint trajectory from the measured angles, or
    None. ``landing`` (radians) asks for the landing limb's solution whose joint 1 is nearest it; the stance after
    must be plannable too."""
    l1, l2, l3, l4 = tumble
    feet = planner.feet(q_now)
    rot0, origin = planner.tumble_frame(feet, l1, l2, l3)
    pose0 = (rot0, -rot0 @ origin)
    ground = (feet - origin) @ rot0.T
    reference = np.asarray(q_now, dtype=float).reshape(planner.n_limbs, 3).copy()
    nominal = planner.stance_angles((l1, l4, l2))[l4]
    reference[l4] = nominal if landing is None else [landing, *nominal[1:]]
    for distance in FOOTHOLDS:
        ground[l4] = [distance, (ground[l1, 1] + ground[l2, 1]) / 2, planner.foot_radius]
        rot, centre, q, inside_old, inside_new = four_feet_poses(planner, ground, tumble, reference.ravel())
        starts, ends = np.flatnonzero(inside_old >= MARGIN), np.flatnonzero(inside_new >= MARGIN)
        if not len(starts) or not len(ends):
            continue
        apart = np.linalg.norm(centre[starts][:, None] - centre[ends][None], axis=-1)
        for flat in np.argsort(apart, axis=None)[:20]:
            a, b = starts[flat // len(ends)], ends[flat % len(ends)]
            pose_a, pose_b = (rot[a], centre[a]), (rot[b], centre[b])
            plan = _moves(planner, q_now, tumble, ground, pose0=pose0, pose_a=pose_a, pose_b=pose_b, q_a=q[a])
            if plan is not None:
                return plan
    return None


def _moves(planner, q_now, tumble, ground, *, pose0, pose_a, pose_b, q_a) -> JointTrajectory | None:
    """The zero-tip tumble from ``q_now`` through poses A and B (rotation body -> tumble frame, centre), or None."""
    l1, l2, l3, l4 = tumble
    (rot_a, centre_a), (rot_b, centre_b) = pose_a, pose_b
    above = ground[l4] + [0.0, 0.0, HOVER]
    hover = planner.ik_near(((above - centre_a) @ rot_a @ planner.base[l4])[None], q_a.reshape(-1, 3)[[l4]])
    reach = planner.body_motion(q_now, [l1, l2, l3], ground, pose0, pose_a, {l4: hover[0]})
    if reach is None or not planner.in_range(reach.q):
        return None
    down = np.linspace(above, ground[l4], 6)
    touch = leg_trajectory(planner, reach.q[-1], l4, down, rot_a, centre_a, rate=planner.rate)
    if touch is None:
        return None
    shift = planner.body_motion(touch.q[-1], [l1, l2, l3, l4], ground, pose_a, pose_b, {})
    if shift is None or not planner.in_range(shift.q):
        return None
    up = np.linspace(ground[l3], ground[l3] + [0.0, 0.0, HOVER], 6)
    lift = leg_trajectory(planner, shift.q[-1], l3, up, rot_b, centre_b, rate=planner.rate)
    if lift is None or planner.stance_plan(lift.q[-1], (l1, l2, l4), (l3,)) is None:
        return None
    return _concatenate([reach, touch, shift, lift])


class ZeroTipController(RollingGaitController):
    """The rolling gait (:class:`RollingGaitController`) with every tip replaced by a zero-tip tumble
    (:func:`zero_tip_plan`): the same choice of tumbles and the same stance moves, never fewer than three feet down.
    Where no zero-tip tumble is plannable it holds its stance (phase ``"done"``) rather than tip."""

    def _tip_plan(self, q: np.ndarray, tumble, future: tuple, landing: float, extra: float = 0.0) -> tuple:
        # ``extra`` pushes a dynamic tip further when the body has not tipped; a zero-tip tumble never waits for one.
        return zero_tip_plan(self.planner, q, tumble, landing), future

    def _begin_next(self, q: np.ndarray):
        super()._begin_next(q)
        if self.phase == "stuck":
            self.phase = "done"
