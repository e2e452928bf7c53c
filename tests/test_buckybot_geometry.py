"""Buckybot geometry generated from the icosahedron against the paper's and the spec's numbers."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from polyenvs.buckybot import geometry as geo


def _axis_rotation(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_physical_scale():
    assert geo.HEXAGON_INRADIUS_CM == pytest.approx(11.95)
    assert geo.ICOSAHEDRON_EDGE_CM == pytest.approx(15.81, abs=0.005)
    assert geo.TRUNCATED_EDGE_CM == pytest.approx(5.27, abs=0.005)
    assert geo.STEP_LENGTH_CM == pytest.approx(9.129, abs=5e-4)
    # Circumradius of the truncated icosahedron: the paper's 26.0 cm diameter within 0.5%.
    e = geo.TRUNCATED_EDGE_CM
    circumradius = e / 4 * np.sqrt(58 + 18 * np.sqrt(5))
    assert 2 * circumradius == pytest.approx(26.12, abs=0.01)
    assert np.degrees(geo.DIHEDRAL_TIP_RAD) == pytest.approx(41.81, abs=0.005)
    assert geo.SENSOR_HEIGHT_CM == pytest.approx(15.93, abs=0.005)


def test_face_normal_elevations_when_resting():
    # From any resting face: 1, 3, 6, 6, 3, 1 normals at -90, -48.19, -19.47, +19.47, +48.19, +90 degrees.
    frames = geo.face_frames()
    for f in range(geo.N_FACES):
        elevation = np.degrees(np.arcsin(np.clip((geo.FACE_NORMALS_HOME @ frames[f].T)[:, 2], -1, 1)))
        counts = collections.Counter(np.round(elevation, 2))
        assert counts == {-90.0: 1, -48.19: 3, -19.47: 6, 19.47: 6, 48.19: 3, 90.0: 1}


def test_upper_sensor_azimuths_and_gaps():
    az = np.degrees(geo.SENSOR_AZIMUTHS_RAD)
    np.testing.assert_allclose(az, [22.24, 97.76, 142.24, 217.76, 262.24, 337.76], atol=0.005)
    gaps = np.diff(np.append(az, az[0] + 360))
    np.testing.assert_allclose(gaps, [75.5225, 44.4775] * 3, atol=1e-4)  # the paper's 75.5 and 44.5
    # Every 44.48° gap is centred on a tip direction (0, 120, 240).
    centres = (az[[5, 1, 3]] + gaps[[5, 1, 3]] / 2) % 360
    np.testing.assert_allclose(np.sort(centres), [0.0, 120.0, 240.0], atol=1e-9)
    assert np.degrees(geo.SENSOR_ELEVATION_RAD) == pytest.approx(19.47, abs=0.005)


def test_face_numbering_is_consistent():
    for f in range(geo.N_FACES):
        neighbours = set(geo.NEIGHBOR[f])
        assert len(neighbours) == 3 and f not in neighbours
        for e in range(3):
            g, b = geo.NEIGHBOR[f, e], geo.BACK_EDGE[f, e]
            assert geo.NEIGHBOR[g, b] == f  # tipping back returns to the same face
            assert geo.BACK_EDGE[g, b] == e
    table = geo.tipping_table()
    assert len(table) == 60
    assert {row["face"] for row in table} == set(range(1, 21))
    assert {row["actuator"] for row in table} == set("ABCDEFGHIJKL")
    # Every actuator is a corner of 5 faces (a pentagon touches five hexagons).
    assert collections.Counter(row["actuator"] for row in table) == dict.fromkeys("ABCDEFGHIJKL", 5)


def test_frame_bookkeeping_matches_rigid_rolling():
    """Tip j rolls the body 41.81° about the edge; the tables must land exactly on the rolled orientation."""
    rng = np.random.default_rng(0)
    for f in range(geo.N_FACES):
        for e0 in range(3):
            heading = rng.uniform(0, 2 * np.pi)
            body = geo.body_rotation(f, e0, heading)
            np.testing.assert_allclose(body @ geo.FACE_NORMALS_HOME[f], [0, 0, -1], atol=1e-12)
            for j in range(3):
                e = (e0 + j) % 3
                direction = np.array([np.cos(heading + 2 * np.pi * j / 3), np.sin(heading + 2 * np.pi * j / 3), 0])
                rolled = _axis_rotation(np.cross([0, 0, 1], direction), geo.DIHEDRAL_TIP_RAD) @ body
                predicted = geo.body_rotation(
                    geo.NEIGHBOR[f, e], geo.BACK_EDGE[f, e], heading + 2 * np.pi * j / 3 + np.pi
                )
                np.testing.assert_allclose(rolled, predicted, atol=1e-12)


def _walk(actions, face=0):
    """Ideal lattice walk in the motion frame; returns positions, faces and body rotations."""
    position, heading, edge0 = np.zeros(2), 0.0, 0
    out = [(position.copy(), face, geo.body_rotation(face, edge0, heading))]
    for j in actions:
        angle = heading + 2 * np.pi * j / 3
        position = position + geo.STEP_LENGTH_CM * np.array([np.cos(angle), np.sin(angle)])
        e = (edge0 + j) % 3
        face, edge0, heading = geo.NEIGHBOR[face, e], geo.BACK_EDGE[face, e], angle + np.pi
        out.append((position.copy(), face, geo.body_rotation(face, edge0, heading)))
    return out


def test_tip_directions_shift_by_60_degrees():
    # After tip j the three directions are the old ones rotated by 60° (mod 120°): back, and +-60° of the move.
    for j in range(3):
        move = 120.0 * j
        new_directions = (move + 180.0 + np.array([0.0, 120.0, 240.0])) % 360
        assert np.allclose(np.sort((new_directions - move) % 360), [60.0, 180.0, 300.0])
        assert np.allclose((new_directions - 60.0) % 120.0, 0.0)


def test_six_tips_round_a_hexagon_rotate_72_degrees_and_thirty_restore():
    walk = _walk([2] * 30)  # always the forward-left tip: once round one honeycomb hexagon every 6 tips
    start_pos, start_face, start_rot = walk[0]
    for k in range(1, 6):
        pos, face, rot = walk[6 * k]
        np.testing.assert_allclose(pos, start_pos, atol=1e-9)
        angle = np.degrees(np.arccos(np.clip((np.trace(rot @ start_rot.T) - 1) / 2, -1, 1)))
        expected = 72.0 * min(k, 5 - k)
        assert angle == pytest.approx(expected, abs=1e-6)
        assert (face == start_face) == (k == 5)
    np.testing.assert_allclose(walk[30][2], start_rot, atol=1e-9)
    # Nowhere before 30 tips does the full state repeat.
    for pos, _face, rot in walk[1:30]:
        assert not (np.allclose(pos, start_pos) and np.allclose(rot, start_rot))


def test_honeycomb_lattice_and_all_sixty_orientations_at_a_site():
    """Breadth-first search over ideal tips: sites form a honeycomb and the origin sees all 60 (face, heading)."""
    seen, frontier = set(), [(np.zeros(2), 0, 0, 0.0)]
    states_at_origin = set()
    for _ in range(24):
        nxt = []
        for pos, face, edge0, heading in frontier:
            # The body's orientation is fixed by (face, yaw of its physical edge 0); yaws are multiples of 60°.
            yaw = int(round(np.degrees(heading - 2 * np.pi / 3 * edge0))) % 360
            key = (round(pos[0], 6) + 0.0, round(pos[1], 6) + 0.0, int(face), yaw)
            if key in seen or np.hypot(*pos) > 3.5 * geo.STEP_LENGTH_CM:  # a small disc is enough, as in A2
                continue
            seen.add(key)
            if np.allclose(pos, 0.0, atol=1e-6):
                states_at_origin.add(key[2:])
            for j in range(3):
                angle = heading + 2 * np.pi * j / 3
                step = geo.STEP_LENGTH_CM * np.array([np.cos(angle), np.sin(angle)])
                e = (edge0 + j) % 3
                nxt.append((pos + step, geo.NEIGHBOR[face, e], geo.BACK_EDGE[face, e], (angle + np.pi) % (2 * np.pi)))
        frontier = nxt
    assert len(states_at_origin) == 60
    assert {s[0] for s in states_at_origin} == set(range(20))
    sites = np.array(sorted({k[:2] for k in seen}))
    distances = np.hypot(*(sites[:, None] - sites[None]).transpose(2, 0, 1))
    np.fill_diagonal(distances, np.inf)
    assert distances.min() == pytest.approx(geo.STEP_LENGTH_CM, abs=1e-6)
    interior = np.hypot(*sites.T) < 2.4 * geo.STEP_LENGTH_CM
    neighbours = (np.abs(distances - geo.STEP_LENGTH_CM) < 1e-6).sum(axis=1)
    assert (neighbours[interior] == 3).all()  # honeycomb: every interior site has exactly three neighbours
