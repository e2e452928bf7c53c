"""Buckybot geometry generated from the icosahedron against the paper's and the spec's numbers."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.simulator import BuckybotParams, BuckybotSimulator
from polyenvs.core.geometry2d import SegmentTable


def _axis_rotation(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _truncated_icosahedron():
    """The robot's 60 corners (cm, home frame), built from the icosahedron by cutting every edge at its thirds."""
    unit = geo.ACTUATOR_AXES_HOME
    gaps = np.linalg.norm(unit[:, None] - unit[None], axis=-1)
    edge = gaps[gaps > 1e-9].min()
    verts = unit * (geo.ICOSAHEDRON_EDGE_CM / edge)
    i, j = np.nonzero(np.triu(np.abs(gaps - edge) < 1e-9))
    assert len(i) == 30
    d = verts[j] - verts[i]
    return np.concatenate([verts[i] + d / 3, verts[i] + 2 * d / 3])


def test_physical_scale_of_the_built_solid():
    """The paper's measured sizes, read off the solid the constants build (not the constants themselves)."""
    corners = _truncated_icosahedron()
    gaps = np.linalg.norm(corners[:, None] - corners[None], axis=-1)
    assert gaps[gaps > 1e-9].min() == pytest.approx(5.27, abs=0.005)  # truncated edge
    assert gaps[gaps > 1e-9].min() == pytest.approx(geo.TRUNCATED_EDGE_CM, abs=1e-9)
    # The paper's 26.0 cm diameter (actuators retracted) is the circumscribed sphere's, within 0.5%.
    diameter = 2 * np.linalg.norm(corners, axis=1).max()
    assert diameter == pytest.approx(26.0, rel=0.005)
    assert diameter == pytest.approx(geo.TRUNCATED_EDGE_CM / 2 * np.sqrt(58 + 18 * np.sqrt(5)), abs=1e-9)
    # Each hexagonal face: six corners on the plane of support along its normal, 23.9 cm from the opposite one.
    support = corners @ geo.FACE_NORMALS_HOME.T  # (60, 20)
    top = support.max(axis=0)
    assert ((support > top - 1e-9).sum(axis=0) == 6).all()
    np.testing.assert_allclose(2 * top, 23.9, atol=1e-9)
    np.testing.assert_allclose(top, geo.HEXAGON_INRADIUS_CM, atol=1e-9)
    for f in range(geo.N_FACES):  # the contact point (and each sensor) is the hexagon's centre, on its normal
        hexagon = corners[support[:, f] > top[f] - 1e-9]
        np.testing.assert_allclose(hexagon.mean(axis=0), top[f] * geo.FACE_NORMALS_HOME[f], atol=1e-9)
    assert geo.STEP_LENGTH_CM == pytest.approx(9.129, abs=5e-4)
    assert np.degrees(geo.DIHEDRAL_TIP_RAD) == pytest.approx(41.81, abs=0.005)


def test_upper_sensors_sit_where_the_solid_puts_them():
    """Resting on any face, the six upper hexagon centres: 15.93 cm up, 11.27 cm out, at the published azimuths."""
    corners = _truncated_icosahedron()
    floor = geo.HEXAGON_INRADIUS_CM
    frames = geo.face_frames()
    faces, _ = geo.upper_sensor_faces()
    assert geo.SENSOR_HEIGHT_CM == pytest.approx(15.93, abs=0.005)
    for f in range(geo.N_FACES):
        local = corners @ frames[f].T
        assert local[:, 2].min() == pytest.approx(-floor, abs=1e-9)  # resting on the floor at z = -11.95
        centres = floor * geo.FACE_NORMALS_HOME[faces[f]] @ frames[f].T
        np.testing.assert_allclose(centres[:, 2] + floor, geo.SENSOR_HEIGHT_CM, atol=1e-9)
        np.testing.assert_allclose(np.hypot(centres[:, 0], centres[:, 1]), geo.SENSOR_HORIZONTAL_OFFSET_CM, atol=1e-9)
        azimuth = np.arctan2(centres[:, 1], centres[:, 0]) % (2 * np.pi)
        np.testing.assert_allclose(azimuth, geo.SENSOR_AZIMUTHS_RAD, atol=1e-9)
        elevation = np.arcsin(centres[:, 2] / floor)
        np.testing.assert_allclose(elevation, geo.SENSOR_ELEVATION_RAD, atol=1e-9)


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


def _bottom_face(verts):
    """Indices of the three lowest corners of an icosahedron (the face it rests on) and the floor height."""
    low = np.argsort(verts[:, 2])[:3]
    return low, verts[low, 2].mean()


def _edge_directions(verts, bottom):
    """World azimuths (deg, sorted) from the contact face's centre to the midpoints of its three edges."""
    centre = verts[bottom].mean(axis=0)
    mids = [
        (verts[a] + verts[b]) / 2 for a, b in ((bottom[0], bottom[1]), (bottom[1], bottom[2]), (bottom[2], bottom[0]))
    ]
    return np.sort([np.degrees(np.arctan2(*(m - centre)[1::-1])) % 360 for m in mids])


def _angle_gap(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("seed", range(4))
def test_rolling_the_solid_shifts_the_tip_directions_by_60_and_the_simulator_agrees(seed):
    """Roll the icosahedron over an edge as a rigid body: it lands on a face 9.129 cm away whose three edges point
    60° (mod 120°) from the old ones, one of them straight back. The simulator's tip must be that roll."""
    rng = np.random.default_rng(seed)
    unit = geo.ACTUATOR_AXES_HOME
    gaps = np.linalg.norm(unit[:, None] - unit[None], axis=-1)
    home = unit * (geo.ICOSAHEDRON_EDGE_CM / gaps[gaps > 1e-9].min())
    face, heading = int(rng.integers(geo.N_FACES)), rng.uniform(0, 2 * np.pi)
    verts = home @ geo.body_rotation(face, 0, heading).T
    bottom, floor = _bottom_face(verts)
    np.testing.assert_allclose(verts[bottom, 2], floor, atol=1e-9)  # flat on the floor
    before = _edge_directions(verts, bottom)
    # The simulator's frame directions 0, 120, 240 from ``heading`` are the resting face's edges.
    frame = (np.degrees(heading) + np.array([0.0, 120.0, 240.0])) % 360
    assert _angle_gap(np.sort(frame)[:, None], before[None]).min(axis=1).max() < 1e-9

    for j in range(3):
        direction = np.radians(frame[j])
        d = np.array([np.cos(direction), np.sin(direction), 0.0])
        # The pivot edge is the one whose midpoint lies along d from the contact centre.
        centre = verts[bottom].mean(axis=0)
        pivot = [v for v in bottom if np.dot(verts[v] - centre, d) > 0]
        assert len(pivot) == 2
        mid = verts[pivot].mean(axis=0)
        rolled = mid + (verts - mid) @ _axis_rotation(np.cross([0, 0, 1], d), geo.DIHEDRAL_TIP_RAD).T
        new_bottom, new_floor = _bottom_face(rolled)
        assert new_floor == pytest.approx(floor, abs=1e-9)
        np.testing.assert_allclose(rolled[new_bottom, 2], floor, atol=1e-9)  # a whole face lands: the 41.81° roll
        assert set(pivot) < set(new_bottom)
        step = rolled[new_bottom].mean(axis=0) - centre
        np.testing.assert_allclose(step[:2], geo.STEP_LENGTH_CM * d[:2], atol=1e-9)
        after = _edge_directions(rolled, new_bottom)
        shifted = (before + 60.0) % 360
        assert _angle_gap(np.sort(shifted)[:, None], after[None]).min(axis=1).max() < 1e-9
        assert _angle_gap(after, frame[j] + 180.0).min() < 1e-9  # one edge leads straight back

        sim = BuckybotSimulator(1, BuckybotParams(noise_scale=0.0))
        sim.set_walls(SegmentTable(np.array([[1e7, -1.0, 1e7, 1.0]])))
        sim.place(0, np.zeros(2), face, heading)
        sim.tip(np.array([j]), np.zeros((1, 3)))
        np.testing.assert_allclose(sim.position[0], step[:2], atol=1e-9)
        new_frame = np.degrees(sim.heading[0]) + np.array([0.0, 120.0, 240.0])
        assert _angle_gap(np.sort(new_frame % 360)[:, None], after[None]).min(axis=1).max() < 1e-9
        assert _angle_gap(new_frame[0], frame[j] + 180.0) < 1e-9  # direction 0 goes back


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
