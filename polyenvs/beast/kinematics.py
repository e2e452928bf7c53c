"""Kinematics of the Platonic beasts' RRR limbs, in plain numpy (no MuJoCo): Tables 1 and 2 of the paper.

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots", section 4.1
(``../shared/seeds/002_*.txt``); the numerical checks are ``../shared/spec/geometry-checks.md`` part B.

Units: metres and radians. Every function is vectorised over leading axes.

Conventions
-----------
- **Limb base frame** (Table 2): origin at the body centre, z along the limb face's outward normal. The 112 mm of
  Table 2's ``Trans(0,0,112)`` is Table 1's d1, counted once (geometry check B1): counted twice, the reach would be
  393 mm beyond the face, contradicting the paper's 25 cm. So a base frame is a pure rotation, and the shoulder
  (joint-2 axis) sits d1 out along its z axis.
- **DH** (standard, Table 1): ``T_i = RotZ(theta_i) Trans(0,0,d_i) Trans(a_i,0,0) RotX(alpha_i)`` with
  link 1 (d1, 0, pi/2), link 2 (0, a2, 0), link 3 (0, a3, 0). The foot point is the origin of frame 3, which the
  MuJoCo model takes as the centre of the spherical foot. MuJoCo's joint angles are exactly these theta.
- **Branches** of the inverse kinematics: ``knee=+1`` puts theta3 > 0 (the knee branch every planted limb uses in
  the working tumble: landing on the other branch makes the next tumble impossible), ``knee=-1`` theta3 < 0;
  ``flip=True`` turns theta1 by pi and reaches over the shoulder (rho < 0: theta2 past 90 degrees).
- **Limb numbers** are 1-based in names and tumbles, 0-based as array indices.

Public names (the environments and the baselines' gaits import them)
--------------------------------------------------------------------
| name | what |
| --- | --- |
| ``Links``, ``PROTOTYPE_LINKS`` | (d1, a2, a3) of Table 1 in metres |
| ``POLYHEDRA``, ``N_LIMBS`` | tetrahedron (4-beast), octahedron (6-beast), cube (8-beast) |
| ``limb_base_frames(polyhedron)`` | (n_limbs, 4, 4) body-from-limb transforms |
| ``limb_directions(polyhedron)`` | (n_limbs, 3) outward limb axes in the body frame |
| ``forward_kinematics(theta, links)`` | foot centre in the limb base frame |
| ``dh_frames(theta, links)`` | the three DH frames (..., 3, 4, 4) in the limb base frame |
| ``foot_in_body(theta, links, polyhedron)`` | every foot in the body frame from (..., n_limbs, 3) angles |
| ``body_to_limb(p_body, polyhedron)`` | body-frame points (..., n_limbs, 3) into each limb's base frame |
| ``inverse_kinematics(p, links, knee, flip)`` | closed form; points beyond the shell clipped onto it |
| ``ik_solutions(p, links)`` | all four closed-form solutions (..., 4, 3) |
| ``reachable(p, links)`` | whether a limb-frame point is inside the workspace shell |
| ``limb_jacobian(theta, links)`` | d foot / d theta, (..., 3, 3) |
| ``ground_frame(p1, p2, p3)`` | the paper's ground frame (origin p1, y to p2, z = y x (p3 - p1)) |
| ``STRAIGHT_OUT`` | the joint angles of a limb straight out along its face normal |
| ``tumbles(n)`` | the 12 tumbles of the 4-beast: even permutations of (1 2 3 4), 1-based |
| ``rot_x``, ``rot_y``, ``rot_z`` | 3x3 rotations (vectorised over the angle) |
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numpy as np

__all__ = [
    "BODY_SIDE",
    "N_LIMBS",
    "POLYHEDRA",
    "PROTOTYPE_LINKS",
    "STRAIGHT_OUT",
    "Links",
    "body_to_limb",
    "dh_frames",
    "foot_in_body",
    "forward_kinematics",
    "ground_frame",
    "ik_solutions",
    "inverse_kinematics",
    "limb_base_frames",
    "limb_directions",
    "limb_jacobian",
    "reachable",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_quat",
    "tumbles",
]


class Links(NamedTuple):
    """Link lengths of Table 1 (m): d1 is the shoulder offset along the face normal, a2 the thigh, a3 the shank."""

    d1: float
    a2: float
    a3: float


#: Table 1 of the paper (mm there): d1 = 112.0, a2 = 98.3, a3 = 140.0 (a3 depends on the foot module).
PROTOTYPE_LINKS = Links(0.112, 0.0983, 0.140)
#: Side of the prototype's octahedral body (paper section 2: "an octahedron of side 17cm").
BODY_SIDE = 0.170
POLYHEDRA = ("tetrahedron", "octahedron", "cube")
N_LIMBS = {"tetrahedron": 4, "octahedron": 6, "cube": 8}
#: Joint angles (rad) that put a limb straight out along its face normal: theta2 = 90 degrees, the rest zero.
STRAIGHT_OUT = np.array([0.0, math.pi / 2, 0.0])
STRAIGHT_OUT.flags.writeable = False

_TILT = math.acos(1.0 / math.sqrt(3.0))  # 54.74 deg: a tetrahedron face normal from the body's 2-fold z axis


def _rot(angle, axis: int) -> np.ndarray:
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.zeros(angle.shape + (3, 3))
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_x(angle) -> np.ndarray:
    return _rot(angle, 0)


def rot_y(angle) -> np.ndarray:
    return _rot(angle, 1)


def rot_z(angle) -> np.ndarray:
    return _rot(angle, 2)


def rotation_quat(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), MuJoCo's order, of a proper rotation matrix."""
    w = math.sqrt(max(0.0, 1.0 + np.trace(rot))) / 2
    if w > 1e-6:
        return np.array(
            [w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w), (rot[1, 0] - rot[0, 1]) / (4 * w)]
        )
    # Half-turns: take the axis from the largest diagonal term.
    i = int(np.argmax(np.diag(rot)))
    j, k = (i + 1) % 3, (i + 2) % 3
    v = np.zeros(3)
    v[i] = math.sqrt(max(0.0, 1.0 + rot[i, i] - rot[j, j] - rot[k, k])) / 2
    v[j] = (rot[j, i] + rot[i, j]) / (4 * v[i])
    v[k] = (rot[k, i] + rot[i, k]) / (4 * v[i])
    return np.array([(rot[k, j] - rot[j, k]) / (4 * v[i]), *v])


def _tetrahedron_rotations() -> np.ndarray:
    """Table 2 without its Trans(0,0,112) (that is d1): RotY/RotX(tilt) . RotZ(offset), limbs 1-4."""
    return np.stack(
        [
            rot_y(_TILT) @ rot_z(-math.pi / 3),
            rot_y(-_TILT) @ rot_z(2 * math.pi / 3),
            rot_x(math.pi + _TILT) @ rot_z(7 * math.pi / 6),
            rot_x(math.pi - _TILT) @ rot_z(math.pi / 6),
        ]
    )


def _limb_rotations(polyhedron: str) -> np.ndarray:
    if polyhedron == "tetrahedron":
        return _tetrahedron_rotations()
    if polyhedron == "cube":
        # The 8-beast has a limb on every face of the same octahedral body: Table 2's four plus the same four turned
        # a quarter turn about the body's z axis, which maps the limb-face tetrahedron onto the control faces
        # (RotZ(pi/2) takes n1, n2, n3, n4 to -n4, -n3, -n1, -n2). The x axes still point at octahedron vertices.
        tet = _tetrahedron_rotations()
        return np.concatenate([tet, rot_z(math.pi / 2) @ tet])
    if polyhedron == "octahedron":
        # The 6-beast: limbs on +x, -x, +y, -y, +z, -z (a cube-like body with a limb on each face). The paper gives
        # no x axes (the hairy-ball theorem forbids a natural choice); ours are proper rotations of the identity.
        return np.stack(
            [
                rot_y(math.pi / 2),
                rot_y(-math.pi / 2),
                rot_x(-math.pi / 2),
                rot_x(math.pi / 2),
                np.eye(3),
                rot_x(math.pi),
            ]
        )
    raise ValueError(f"polyhedron must be one of {list(POLYHEDRA)}, got {polyhedron!r}")


def limb_base_frames(polyhedron: str = "tetrahedron") -> np.ndarray:
    """Body-from-limb-base homogeneous transforms, (n_limbs, 4, 4): rotation only, origin at the body centre."""
    rot = _limb_rotations(polyhedron)
    out = np.zeros((len(rot), 4, 4))
    out[:, :3, :3] = rot
    out[:, 3, 3] = 1.0
    return out


def limb_directions(polyhedron: str = "tetrahedron") -> np.ndarray:
    """Outward limb axes (the base frames' z axes) in the body frame, (n_limbs, 3)."""
    return _limb_rotations(polyhedron)[:, :, 2].copy()


def _split(theta):
    theta = np.asarray(theta, dtype=float)
    if theta.shape[-1:] != (3,):
        raise ValueError(f"theta must have a last axis of 3 joint angles, got shape {theta.shape}")
    return theta[..., 0], theta[..., 1], theta[..., 2]


def forward_kinematics(theta, links: Links = PROTOTYPE_LINKS) -> np.ndarray:
    """Foot centre in the limb base frame, (..., 3), from joint angles (..., 3) (geometry check B2)."""
    t1, t2, t3 = _split(theta)
    d1, a2, a3 = links
    rho = a2 * np.cos(t2) + a3 * np.cos(t2 + t3)
    return np.stack([rho * np.cos(t1), rho * np.sin(t1), d1 + a2 * np.sin(t2) + a3 * np.sin(t2 + t3)], axis=-1)


def _dh(theta, d: float, a: float, alpha: float) -> np.ndarray:
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, :] = np.stack([c, -s * ca, s * sa, a * c], axis=-1)
    out[..., 1, :] = np.stack([s, c * ca, -c * sa, a * s], axis=-1)
    out[..., 2, 1] = sa
    out[..., 2, 2] = ca
    out[..., 2, 3] = d
    out[..., 3, 3] = 1.0
    return out


def dh_frames(theta, links: Links = PROTOTYPE_LINKS) -> np.ndarray:
    """Frames 1, 2, 3 of the DH chain in the limb base frame, (..., 3, 4, 4); frame 3's origin is the foot."""
    t1, t2, t3 = _split(theta)
    f1 = _dh(t1, links.d1, 0.0, math.pi / 2)
    f2 = f1 @ _dh(t2, 0.0, links.a2, 0.0)
    f3 = f2 @ _dh(t3, 0.0, links.a3, 0.0)
    return np.stack([f1, f2, f3], axis=-3)


def foot_in_body(theta, links: Links = PROTOTYPE_LINKS, polyhedron: str = "tetrahedron") -> np.ndarray:
    """Every foot centre in the body frame, (..., n_limbs, 3), from joint angles (..., n_limbs, 3)."""
    rot = _limb_rotations(polyhedron)
    theta = np.asarray(theta, dtype=float)
    if theta.shape[-2:] != (len(rot), 3):
        raise ValueError(f"theta must end in ({len(rot)}, 3) for the {polyhedron}, got shape {theta.shape}")
    return np.einsum("lij,...lj->...li", rot, forward_kinematics(theta, links))


def body_to_limb(p_body, polyhedron: str = "tetrahedron") -> np.ndarray:
    """Body-frame points, one per limb (..., n_limbs, 3), expressed in each limb's base frame."""
    rot = _limb_rotations(polyhedron)
    return np.einsum("lji,...lj->...li", rot, np.asarray(p_body, dtype=float))


def _wrap(angle):
    return np.mod(angle + np.pi, 2 * np.pi) - np.pi


def _planar(p, links: Links, flip):
    """rho (signed radial distance, negative for the flipped branch), h (height above the shoulder), theta1."""
    p = np.asarray(p, dtype=float)
    if p.shape[-1:] != (3,):
        raise ValueError(f"p must have a last axis of 3 coordinates, got shape {p.shape}")
    radial = np.hypot(p[..., 0], p[..., 1])
    t1 = np.arctan2(p[..., 1], p[..., 0])
    flip = np.asarray(flip, dtype=bool)
    rho = np.where(flip, -radial, radial)
    t1 = np.where(flip, _wrap(t1 + np.pi), t1)
    return rho, p[..., 2] - links.d1, t1


def _cos_knee(rho, h, links: Links):
    return (rho**2 + h**2 - links.a2**2 - links.a3**2) / (2 * links.a2 * links.a3)


def reachable(p, links: Links = PROTOTYPE_LINKS, tol: float = 1e-9) -> np.ndarray:
    """Whether limb-frame points lie in the workspace shell |a2 - a3| <= |p - shoulder| <= a2 + a3."""
    rho, h, _ = _planar(p, links, False)
    return np.abs(_cos_knee(rho, h, links)) <= 1.0 + tol


def inverse_kinematics(p, links: Links = PROTOTYPE_LINKS, knee=1, flip=False) -> np.ndarray:
    """Joint angles (..., 3) that put the foot centre at limb-frame point ``p`` (..., 3), closed form (B2).

    ``knee`` (+1 or -1, broadcastable) is the sign of theta3; ``flip`` (broadcastable bools) takes theta1 + pi and
    reaches over the shoulder. A point outside the workspace shell is clipped onto it (the limb points straight at
    it, or folds fully), so the result is always finite; ``reachable`` tells which points were clipped. theta1 is
    in (-pi, pi]; on the joint-1 axis (rho = 0) theta1 is 0, or pi when flipped.
    """
    rho, h, t1 = _planar(p, links, flip)
    knee = np.asarray(knee)
    if not np.all(np.abs(knee) == 1):
        raise ValueError(f"knee must be +1 or -1, got {knee!r}")
    t3 = knee * np.arccos(np.clip(_cos_knee(rho, h, links), -1.0, 1.0))
    t2 = np.arctan2(h, rho) - np.arctan2(links.a3 * np.sin(t3), links.a2 + links.a3 * np.cos(t3))
    return np.stack(np.broadcast_arrays(t1, _wrap(t2), t3), axis=-1)


def ik_solutions(p, links: Links = PROTOTYPE_LINKS) -> np.ndarray:
    """All four closed-form solutions, (..., 4, 3), ordered (knee +1, knee -1, flipped knee +1, flipped knee -1)."""
    p = np.asarray(p, dtype=float)[..., None, :]
    knee = np.array([1, -1, 1, -1])
    flip = np.array([False, False, True, True])
    return inverse_kinematics(p, links, knee=knee, flip=flip)


def limb_jacobian(theta, links: Links = PROTOTYPE_LINKS) -> np.ndarray:
    """d(foot in the limb base frame)/d(theta), (..., 3, 3): rows x, y, z; columns theta1, theta2, theta3."""
    t1, t2, t3 = _split(theta)
    _, a2, a3 = links
    c1, s1 = np.cos(t1), np.sin(t1)
    s2, c2 = np.sin(t2), np.cos(t2)
    s23, c23 = np.sin(t2 + t3), np.cos(t2 + t3)
    rho = a2 * c2 + a3 * c23
    drho2, drho3 = -a2 * s2 - a3 * s23, -a3 * s23
    zero = np.zeros_like(rho)
    return np.stack(
        [
            np.stack([-rho * s1, drho2 * c1, drho3 * c1], axis=-1),
            np.stack([rho * c1, drho2 * s1, drho3 * s1], axis=-1),
            np.stack([zero, a2 * c2 + a3 * c23, a3 * c23], axis=-1),
        ],
        axis=-2,
    )


def ground_frame(p1, p2, p3) -> np.ndarray:
    """The paper's ground frame (section 4.2) as a (..., 4, 4) transform into the frame the feet are given in.

    Origin at foot 1, y towards foot 2, z along y x (p3 - p1) (the side of the free limb for an even permutation,
    geometry check B4), x = y x z. With feet 1, 2, 3 on the ground of a (1234) tumble, z points up and x forwards,
    away from foot 3.
    """
    p1, p2, p3 = (np.asarray(p, dtype=float) for p in (p1, p2, p3))
    y = p2 - p1
    y = y / np.linalg.norm(y, axis=-1, keepdims=True)
    z = np.cross(y, p3 - p1)
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    x = np.cross(y, z)
    shape = np.broadcast_shapes(p1.shape, p2.shape, p3.shape)[:-1]
    out = np.zeros(shape + (4, 4))
    out[..., :3, 0] = x
    out[..., :3, 1] = y
    out[..., :3, 2] = z
    out[..., :3, 3] = p1
    out[..., 3, 3] = 1.0
    return out


def tumbles(n: int = 4) -> np.ndarray:
    """The tumbles of an n-limbed tetrahedral beast: the even permutations of (1 .. n), 1-based, (n!/2, n).

    A row (l1 l2 l3 l4) tips over the edge of feet l1, l2; l3 starts planted and ends free, l4 lands (paper section 3).
    For n = 4 the 12 rows map one-to-one onto (free limb, tipping edge) pairs. Rows in lexicographic order.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise ValueError(f"n must be an integer >= 2, got {n!r}")
    rows = []
    for perm in itertools.permutations(range(1, n + 1)):
        inversions = sum(perm[i] > perm[j] for i in range(n) for j in range(i + 1, n))
        if inversions % 2 == 0:
            rows.append(perm)
    return np.array(rows, dtype=np.int64)
