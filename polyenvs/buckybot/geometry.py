"""Buckybot's rigid geometry, generated from a regular icosahedron.

Buckybot is a truncated icosahedron: it rests on its 20 hexagonal faces and tips by extending one of its 12
pentagonal faces (linear actuators). For motion it is an icosahedron resting on one of its 20 triangular faces
(Buckybot paper, "Geometry and Sensing"). Nothing here is typed in: the face numbering, the actuator letters, the
tipping table and the sensor directions all come from the icosahedron's vertices.

Conventions
-----------
* *Home frame*: the body resting on face 1 (its outward normal points straight down, -z), with the tip over the
  edge opposite actuator A pointing along +x.
* Faces are numbered 1..20 by ring of elevation in the home frame (-90°, -48.19°, -19.47°, +19.47°, +48.19°,
  +90°), then by azimuth in [0°, 360°). Actuators (icosahedron vertices) are lettered A..L the same way
  (rings at -52.62°, -10.81°, +10.81°, +52.62°).
* Each face has three *edges*, numbered 0, 1, 2 counter-clockwise seen from above when resting on that face;
  edge 0 is the edge opposite the face's alphabetically first corner actuator. Tipping over edge ``e`` is done by
  extending the corner actuator opposite it (``FACE_CORNER_ACTUATOR[f, e]``).
* Arrays are 0-based (face index ``f`` is face number ``f + 1``); the public tables in ``tipping_table()`` use
  the 1-based numbers and letters of the robot.
"""

from __future__ import annotations

import itertools

import numpy as np

from polyenvs.core import libm

__all__ = [
    "ACTUATOR_AXES_HOME",
    "ACTUATOR_LETTERS",
    "BACK_EDGE",
    "BODY_RADIUS_CM",
    "DIHEDRAL_TIP_RAD",
    "FACE_CORNER_ACTUATOR",
    "FACE_NORMALS_HOME",
    "HEXAGON_INRADIUS_CM",
    "ICOSAHEDRON_EDGE_CM",
    "N_FACES",
    "NEIGHBOR",
    "SENSOR_AZIMUTHS_RAD",
    "SENSOR_ELEVATION_RAD",
    "SENSOR_HEIGHT_CM",
    "SENSOR_HORIZONTAL_OFFSET_CM",
    "STEP_LENGTH_CM",
    "TRUNCATED_EDGE_CM",
    "body_rotation",
    "face_frames",
    "tipping_table",
    "upper_sensor_faces",
]

# --- Physical scale (Buckybot paper, "Actuation and Control") -------------------------------------------------
#: Distance from the body centre to a hexagonal face: half the 23.9 cm between opposite hexagons.
HEXAGON_INRADIUS_CM = 23.9 / 2.0
_PHI = (1.0 + 5.0**0.5) / 2.0
#: Parent icosahedron edge whose face inradius is 11.95 cm: r = a * phi^2 / (2 sqrt 3), so a = 15.81 cm.
ICOSAHEDRON_EDGE_CM = HEXAGON_INRADIUS_CM * 2.0 * 3.0**0.5 / _PHI**2
#: Truncated-icosahedron edge (a third of the parent edge): 5.27 cm.
TRUNCATED_EDGE_CM = ICOSAHEDRON_EDGE_CM / 3.0
#: Ideal distance between successive contact-face centres, a / sqrt(3) = 9.129 cm.
STEP_LENGTH_CM = ICOSAHEDRON_EDGE_CM / 3.0**0.5
#: Body radius used for wall contact (spec: 13 cm; the truncated icosahedron's circumradius is 13.06 cm).
BODY_RADIUS_CM = 13.0
N_FACES = 20


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit-circumradius icosahedron: (12, 3) vertices and (20, 3) vertex-index triples (unordered)."""
    verts = []
    for a, b in itertools.product((-1.0, 1.0), repeat=2):
        verts += [(0.0, a, b * _PHI), (a, b * _PHI, 0.0), (b * _PHI, 0.0, a)]
    verts = np.array(verts)
    verts /= np.linalg.norm(verts[0])
    edge = np.min([np.linalg.norm(u - v) for u, v in itertools.combinations(verts, 2)])
    faces = [
        tri
        for tri in itertools.combinations(range(12), 3)
        if all(abs(np.linalg.norm(verts[i] - verts[j]) - edge) < 1e-9 for i, j in itertools.combinations(tri, 2))
    ]
    return verts, np.array(faces)


def _rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A rotation matrix taking unit vector u onto unit vector v (Rodrigues)."""
    axis = np.cross(u, v)
    s, c = np.linalg.norm(axis), float(np.dot(u, v))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # Antiparallel: rotate by pi about any axis perpendicular to u.
        perp = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        return 2.0 * np.outer(perp, perp) - np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def _rot_z(angle: float) -> np.ndarray:
    c, s = libm.cos(angle), libm.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ring_order(directions: np.ndarray) -> np.ndarray:
    """Order unit vectors by elevation ring (lowest first), then azimuth in [0, 2 pi)."""
    elevation = np.round(np.degrees(libm.arcsin(np.clip(directions[:, 2], -1, 1))), 6)
    azimuth = np.round(np.degrees(libm.arctan2(directions[:, 1], directions[:, 0])) % 360.0, 6) % 360.0
    return np.lexsort((azimuth, elevation))


def _build():
    verts, faces = _icosahedron()
    centroids = verts[faces].mean(axis=1)
    normals = centroids / np.linalg.norm(centroids, axis=1, keepdims=True)

    # Rest on an arbitrary face, then yaw so that a corner vertex of that face points to azimuth 180°: the edge
    # opposite it (tip direction) then points to 0°. Letters/numbers are assigned in this frame, and the corner at
    # 180° is the lowest-azimuth... not necessarily "A", so re-yaw once the letters exist (below).
    rest = 0
    rot = _rotation_between(normals[rest], np.array([0.0, 0.0, -1.0]))
    corner = rot @ verts[faces[rest][0]]
    rot = _rot_z(np.pi - libm.arctan2(corner[1], corner[0])) @ rot
    v_home, n_home = verts @ rot.T, normals @ rot.T

    face_order = _ring_order(n_home)  # new index -> old index
    vert_order = _ring_order(v_home)
    vert_new = np.empty(12, dtype=int)
    vert_new[vert_order] = np.arange(12)
    faces = vert_new[faces[face_order]]
    v_home, n_home = v_home[vert_order], n_home[face_order]

    # Face 1 (index 0) is the resting face. Re-yaw so the edge opposite its first-lettered corner points along +x.
    first_corner = v_home[faces[0].min()]
    yaw = _rot_z(np.pi - libm.arctan2(first_corner[1], first_corner[0]))
    v_home, n_home = v_home @ yaw.T, n_home @ yaw.T
    return v_home, n_home, faces


_VERTS_HOME, FACE_NORMALS_HOME, _FACE_VERTS = _build()
#: Unit axes of the 12 actuators (icosahedron vertices, A..L) in the home frame.
ACTUATOR_AXES_HOME = _VERTS_HOME


def face_frames() -> np.ndarray:
    """(20, 3, 3) rotations taking body (home-frame) vectors into each face's resting frame.

    In face f's frame the face's outward normal is -z (it rests on the floor) and its edge 0 (opposite its
    first-lettered corner actuator) points along +x. Edges 1 and 2 follow counter-clockwise at 120° and 240°.
    """
    frames = np.empty((N_FACES, 3, 3))
    for f in range(N_FACES):
        z = -FACE_NORMALS_HOME[f]
        centroid = _VERTS_HOME[_FACE_VERTS[f]].mean(axis=0)
        corner = _VERTS_HOME[_FACE_VERTS[f].min()]
        x = centroid - corner  # from the corner through the centroid towards the opposite edge
        x -= np.dot(x, z) * z
        x /= np.linalg.norm(x)
        frames[f] = np.stack([x, np.cross(z, x), z])
    return frames


_FRAMES = face_frames()


def _face_corners_ccw() -> np.ndarray:
    """(20, 3) vertex index opposite edge 0, 1, 2 of each face (edges counter-clockwise from above)."""
    corners = np.empty((N_FACES, 3), dtype=int)
    for f in range(N_FACES):
        local = _VERTS_HOME[_FACE_VERTS[f]] @ _FRAMES[f].T
        azimuth = libm.arctan2(local[:, 1], local[:, 0]) % (2 * np.pi)
        # Edge e's tip direction is at 120° e; the corner opposite it sits at 120° e + 180°.
        for e in range(3):
            target = (np.radians(120.0 * e) + np.pi) % (2 * np.pi)
            gap = np.abs((azimuth - target + np.pi) % (2 * np.pi) - np.pi)
            corners[f, e] = _FACE_VERTS[f][np.argmin(gap)]
    return corners


#: Actuator (vertex) index extended to tip face f over its edge e: the corner opposite that edge.
FACE_CORNER_ACTUATOR = _face_corners_ccw()
ACTUATOR_LETTERS = "ABCDEFGHIJKL"


def _neighbours() -> tuple[np.ndarray, np.ndarray]:
    neighbor = np.empty((N_FACES, 3), dtype=np.int64)
    back = np.empty((N_FACES, 3), dtype=np.int64)
    for f in range(N_FACES):
        for e in range(3):
            edge_verts = set(_FACE_VERTS[f]) - {FACE_CORNER_ACTUATOR[f, e]}
            (g,) = [g for g in range(N_FACES) if g != f and edge_verts <= set(_FACE_VERTS[g])]
            neighbor[f, e] = g
            back[f, e] = int(np.flatnonzero(~np.isin(FACE_CORNER_ACTUATOR[g], list(edge_verts)))[0])
    return neighbor, back


#: NEIGHBOR[f, e]: the face reached by tipping face f over its edge e.
#: BACK_EDGE[f, e]: the edge of that new face that tips the robot back onto f.
NEIGHBOR, BACK_EDGE = _neighbours()

#: Rotation of the body in one tip: 180° minus the icosahedron's dihedral angle (138.19°), i.e. 41.81°.
DIHEDRAL_TIP_RAD = float(np.pi - libm.arccos(-(5.0**0.5) / 3.0))


def upper_sensor_faces() -> tuple[np.ndarray, np.ndarray]:
    """For each resting face, the six faces whose range finders point 19.47° above the horizon.

    Returns ``(faces, azimuths)``: (20, 6) face indices ordered by azimuth in the resting face's frame, and the six
    azimuths (radians, identical for every face) they point at.
    """
    faces = np.empty((N_FACES, 6), dtype=np.int64)
    azimuths = None
    for f in range(N_FACES):
        local = FACE_NORMALS_HOME @ _FRAMES[f].T
        upper = np.flatnonzero(np.abs(local[:, 2] - 1.0 / 3.0) < 1e-9)
        az = libm.arctan2(local[upper, 1], local[upper, 0]) % (2 * np.pi)
        order = np.argsort(az)
        faces[f] = upper[order]
        azimuths = az[order] if azimuths is None else azimuths
        if not np.allclose(az[order], azimuths, atol=1e-9):
            raise AssertionError("face frames are not congruent")  # the icosahedron's symmetry guarantees this
    return faces, azimuths


_UPPER_FACES, SENSOR_AZIMUTHS_RAD = upper_sensor_faces()
#: Elevation of the six upper range finders, asin(1/3) = 19.47° (Buckybot paper, "Geometry and Sensing").
SENSOR_ELEVATION_RAD = float(libm.arcsin(1.0 / 3.0))
#: Horizontal distance of a sensor (hexagon centre) from the body's vertical axis: 11.95 cos(19.47°) = 11.27 cm.
SENSOR_HORIZONTAL_OFFSET_CM = HEXAGON_INRADIUS_CM * libm.cos(SENSOR_ELEVATION_RAD)
#: Height of an upper sensor above the floor: 11.95 + 11.95 sin(19.47°) = 15.93 cm.
SENSOR_HEIGHT_CM = HEXAGON_INRADIUS_CM * (1.0 + libm.sin(SENSOR_ELEVATION_RAD))


def body_rotation(face: int, edge0: int, heading: float) -> np.ndarray:
    """Body-to-world rotation of a robot resting on ``face`` whose edge ``edge0`` points at world azimuth ``heading``."""
    return _rot_z(heading - np.radians(120.0 * edge0)) @ _FRAMES[face]


def tipping_table() -> list[dict]:
    """The robot's tipping table, with the paper's labels: faces 1-20 and actuators A-L.

    One row per (face, edge): the actuator to extend, the face the robot lands on, and the actuator that tips it
    back. Generated from the geometry (see the module docstring for the numbering rule).
    """
    rows = []
    for f in range(N_FACES):
        for e in range(3):
            g, b = NEIGHBOR[f, e], BACK_EDGE[f, e]
            rows.append(
                {
                    "face": f + 1,
                    "edge": e,
                    "actuator": ACTUATOR_LETTERS[FACE_CORNER_ACTUATOR[f, e]],
                    "lands_on": int(g) + 1,
                    "back_actuator": ACTUATOR_LETTERS[FACE_CORNER_ACTUATOR[g, b]],
                }
            )
    return rows
