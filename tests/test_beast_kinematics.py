"""Kinematics of the beasts against the paper's tables and the geometry checks B1-B4 (numpy only, no MuJoCo)."""

import math

import numpy as np
import pytest

from polyenvs.beast import kinematics as K

MM = 1e-3
RNG_SEED = 7


def _upright(direction):
    """A rotation (rows = world axes in body coordinates) that turns ``direction`` straight up."""
    z = np.asarray(direction, dtype=float)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def _random_theta(rng, n):
    return rng.uniform([-math.pi, -math.pi, -math.pi], [math.pi, math.pi, math.pi], size=(n, 3))


def test_tetrahedron_limb_axes_are_109_47_degrees_apart_and_right_handed():
    d = K.limb_directions("tetrahedron")
    angles = np.degrees(np.arccos(np.clip(d @ d.T, -1, 1)))[np.triu_indices(4, 1)]
    np.testing.assert_allclose(angles, math.degrees(math.acos(-1 / 3)), atol=1e-9)
    assert math.isclose(math.degrees(math.acos(-1 / 3)), 109.47, abs_tol=0.005)
    np.testing.assert_allclose(d.sum(axis=0), 0, atol=1e-12)
    # B1: seen from limb 4, 1 -> 2 -> 3 runs counter-clockwise (the paper's right-handed numbering).
    assert np.dot(np.cross(d[1] - d[0], d[2] - d[0]), d[3] - d[0]) > 0
    # B1's face normals, n1 = (sqrt(2/3), 0, 1/sqrt(3)) ...
    s, c = math.sqrt(2 / 3), 1 / math.sqrt(3)
    np.testing.assert_allclose(d, [[s, 0, c], [-s, 0, c], [0, s, -c], [0, -s, -c]], atol=1e-12)


def _table2(limb):
    """Table 2 written out literally, including its Trans(0, 0, 112), as a 4x4 transform in metres."""
    tilt = math.acos(1 / math.sqrt(3))
    rows = [
        (K.rot_y(tilt), -math.pi / 3),
        (K.rot_y(-tilt), 2 * math.pi / 3),
        (K.rot_x(math.pi + tilt), 7 * math.pi / 6),
        (K.rot_x(math.pi - tilt), math.pi / 6),
    ]
    rot, offset = rows[limb]
    first = np.eye(4)
    first[:3, :3] = rot
    trans = np.eye(4)
    trans[2, 3] = 0.112
    last = np.eye(4)
    last[:3, :3] = K.rot_z(offset)
    return first @ trans @ last


def test_table2_frames_reproduced_with_the_112_mm_counted_once():
    frames = K.limb_base_frames("tetrahedron")
    rng = np.random.default_rng(RNG_SEED)
    theta = _random_theta(rng, 50)
    once_elsewhere = K.Links(0.0, K.PROTOTYPE_LINKS.a2, K.PROTOTYPE_LINKS.a3)
    for limb in range(4):
        table = _table2(limb)
        np.testing.assert_allclose(frames[limb][:3, :3], table[:3, :3], atol=1e-12)
        # Our frame (rotation only) + DH with d1 = 112 == Table 2 with its Trans(0,0,112) + DH with d1 = 0.
        ours = K.foot_in_body(np.repeat(theta[:, None], 4, axis=1))[:, limb]
        foot = K.forward_kinematics(theta, once_elsewhere)
        literal = (table[:3, :3] @ foot.T).T + table[:3, 3]
        np.testing.assert_allclose(ours, literal, atol=1e-12)


def test_table2_x_axes_point_from_the_face_centre_to_a_vertex_of_the_octahedron():
    circumradius = K.BODY_SIDE / math.sqrt(2)
    vertices = circumradius * np.array(
        [[0, 0, 1], [0, 0, -1], [1, 1, 0], [1, -1, 0], [-1, 1, 0], [-1, -1, 0]], dtype=float
    )
    vertices[2:, :2] /= math.sqrt(2)
    inradius = K.BODY_SIDE / math.sqrt(6)
    for frame in K.limb_base_frames("tetrahedron"):
        centre = inradius * frame[:3, 2]
        to_vertex = vertices - centre
        on_face = np.isclose(to_vertex @ frame[:3, 2], 0, atol=1e-12)
        assert on_face.sum() == 3  # the limb face is a face of the body
        cosines = to_vertex[on_face] @ frame[:3, 0] / np.linalg.norm(to_vertex[on_face], axis=1)
        assert np.isclose(cosines.max(), 1.0, atol=1e-12)


def test_reach_is_about_25_cm_from_the_body_surface_only_with_the_112_mm_counted_once():
    links = K.PROTOTYPE_LINKS
    straight = K.forward_kinematics(np.array([0.0, math.pi / 2, 0.0]), links)
    reach = np.linalg.norm(straight)
    assert math.isclose(reach, 0.3503, abs_tol=1e-9)
    inradius, circumradius = K.BODY_SIDE / math.sqrt(6), K.BODY_SIDE / math.sqrt(2)
    assert math.isclose(inradius, 0.06940, abs_tol=1e-5)
    # B1: 280.9 mm beyond the face plane, 230.1 mm beyond the vertex sphere; the paper's 25 cm lies between.
    assert reach - circumradius < 0.25 < reach - inradius
    assert math.isclose(reach - inradius, 0.2809, abs_tol=1e-4)
    assert math.isclose(reach - circumradius, 0.2301, abs_tol=1e-4)
    # Counted twice the shoulder would sit at 224 mm and the reach be 393 mm beyond the face: inconsistent.
    assert (0.224 + links.a2 + links.a3) - inradius > 0.39


def test_dh_product_equals_the_closed_form():
    rng = np.random.default_rng(RNG_SEED)
    theta = _random_theta(rng, 500)
    frames = K.dh_frames(theta)
    np.testing.assert_allclose(frames[:, 2, :3, 3], K.forward_kinematics(theta), atol=1e-15)
    np.testing.assert_allclose(frames[:, 0, :3, 3], [[0, 0, 0.112]] * 500, atol=1e-15)
    # Every DH frame is a proper rotation.
    rot = frames[..., :3, :3]
    np.testing.assert_allclose(rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)


@pytest.mark.parametrize("knee", [1, -1])
@pytest.mark.parametrize("flip", [False, True])
def test_fk_ik_round_trip_over_the_workspace_on_both_branches(knee, flip):
    rng = np.random.default_rng(RNG_SEED)
    links = K.PROTOTYPE_LINKS
    # Points filling the shell |a2 - a3| .. a2 + a3 around the shoulder, away from its singular boundaries.
    n = 4000
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = rng.uniform(abs(links.a3 - links.a2) + 1e-3, links.a2 + links.a3 - 1e-3, size=(n, 1))
    p = direction * radius + [0, 0, links.d1]
    assert K.reachable(p).all()
    theta = K.inverse_kinematics(p, links, knee=knee, flip=flip)
    np.testing.assert_allclose(K.forward_kinematics(theta, links), p, atol=1e-12)
    assert (np.sign(theta[:, 2]) == knee).all()
    # The flipped branch reaches over the shoulder: negative radial distance in the theta1 direction.
    rho = links.a2 * np.cos(theta[:, 1]) + links.a3 * np.cos(theta[:, 1] + theta[:, 2])
    assert ((rho < 0) == flip).all()
    assert (np.abs(theta) <= math.pi + 1e-12).all()


def test_every_joint_vector_is_among_its_four_ik_solutions():
    rng = np.random.default_rng(RNG_SEED)
    theta = _random_theta(rng, 3000)
    solutions = K.ik_solutions(K.forward_kinematics(theta))
    assert solutions.shape == (3000, 4, 3)
    np.testing.assert_allclose(
        K.forward_kinematics(solutions), np.repeat(K.forward_kinematics(theta)[:, None], 4, axis=1), atol=1e-12
    )
    wrapped = np.angle(np.exp(1j * (solutions - theta[:, None])))
    assert (np.abs(wrapped).max(axis=2).min(axis=1) < 1e-7).all()


def test_unreachable_points_are_clipped_onto_the_shell():
    links = K.PROTOTYPE_LINKS
    far = np.array([[0.5, 0.0, 0.112], [0.0, 0.0, 0.112 + 0.01]])
    assert not K.reachable(far).any()
    theta = K.inverse_kinematics(far, links)
    assert np.isfinite(theta).all()
    reach = np.linalg.norm(K.forward_kinematics(theta, links) - [0, 0, links.d1], axis=1)
    np.testing.assert_allclose(reach, [links.a2 + links.a3, links.a3 - links.a2], atol=1e-12)


def test_limb_jacobian_matches_finite_differences():
    rng = np.random.default_rng(RNG_SEED)
    theta = _random_theta(rng, 200)
    jac = K.limb_jacobian(theta)
    eps = 1e-6
    for k in range(3):
        step = np.zeros(3)
        step[k] = eps
        numeric = (K.forward_kinematics(theta + step) - K.forward_kinematics(theta - step)) / (2 * eps)
        np.testing.assert_allclose(jac[:, :, k], numeric, atol=1e-9)
    # Singular when the limb is straight (theta3 = 0), regular on the knee branch away from it.
    assert abs(np.linalg.det(K.limb_jacobian([0.3, 0.5, 0.0]))) < 1e-15
    assert abs(np.linalg.det(K.limb_jacobian([0.3, 0.5, 1.0]))) > 1e-4


def test_exactly_twelve_tumbles_as_in_b4():
    rows = K.tumbles()
    assert rows.shape == (12, 4)
    listed = "1234 1342 1423 2143 2314 2431 3124 3241 3412 4132 4213 4321".split()
    assert ["".join(map(str, r)) for r in rows] == listed
    # One-to-one with (free limb, tipping edge): the free limb l3 and the unordered edge {l1, l2}.
    assert len({(r[2], frozenset(r[:2])) for r in rows}) == 12
    # The paper's ground frame z = y x (p(l3) - p(l1)) points to the free limb exactly for even permutations.
    feet = K.limb_directions()
    for r in rows:
        p = feet[np.asarray(r) - 1]
        frame = K.ground_frame(p[0], p[1], p[2])
        assert np.dot(frame[:3, 2], p[3] - p[0]) > 0
    with pytest.raises(ValueError, match="n"):
        K.tumbles(True)


def test_nominal_three_foot_stance_b3():
    # Limb 4 straight up, stance limbs with thigh horizontal and shank vertical: (0, 70.53, 90) etc.
    theta = np.radians([[0, 70.53, 90], [120, 70.53, 90], [-120, 70.53, 90], [0, 90, 0]])
    feet = K.foot_in_body(theta) @ _upright(K.limb_directions()[3]).T
    np.testing.assert_allclose(feet[:3, 2], -0.17733, atol=0.05 * MM)  # body centre 177.33 mm up
    radius = np.hypot(*(feet[:3, :2] - feet[:3, :2].mean(axis=0)).T)
    np.testing.assert_allclose(radius, 0.20389, atol=0.05 * MM)  # feet at radius 203.89 mm
    np.testing.assert_allclose(np.linalg.norm(feet[0] - feet[1]), 0.3532, atol=0.1 * MM)
    np.testing.assert_allclose(feet[:3, :2].mean(axis=0), 0, atol=1e-12)  # COM over the centroid
    np.testing.assert_allclose(feet[3], [0, 0, 0.3503], atol=1e-12)
    # The equivalent forms (theta1 +- 180, 109.47, -90) put the feet at the same places.
    other = theta.copy()
    other[:3] = np.radians([[180, 109.47, -90], [-60, 109.47, -90], [60, 109.47, -90]])
    np.testing.assert_allclose(K.foot_in_body(other)[:3], K.foot_in_body(theta)[:3], atol=0.05 * MM)


def test_working_tumble_start_stance_k0():
    # The feasibility study's start stance: feet on an equilateral pattern of side 300 mm, body centre 168 mm above
    # the ground with 18 mm spherical feet.
    theta = np.radians([[0, 56.0, 115.8], [120, 56.0, 115.8], [-120, 56.0, 115.8], [0, 90, 0]])
    feet = K.foot_in_body(theta) @ _upright(K.limb_directions()[3]).T
    sides = np.linalg.norm(feet[[0, 1, 2]] - feet[[1, 2, 0]], axis=1)
    np.testing.assert_allclose(sides, 0.300, atol=0.5 * MM)
    np.testing.assert_allclose(-feet[:3, 2] + 0.018, 0.168, atol=0.2 * MM)


def test_four_feet_down_in_the_tilted_mid_tumble_pose_b3():
    # Body flipped so its 2-fold z axis points down; body x along -y (feet 1, 2 at -+y), body y along -x.
    rot = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    directions = K.limb_directions() @ rot.T
    elevations = np.degrees(np.arcsin(directions[:, 2]))
    np.testing.assert_allclose(elevations, [-35.26, -35.26, 35.26, 35.26], atol=0.01)
    theta = np.radians([[-120, 155.54, -106.36], [-120, 155.54, -106.36], [60, 4.35, -41.31], [60, 4.35, -41.31]])
    feet = K.foot_in_body(theta) @ rot.T + [0, 0, 0.151]
    expected = [[0, -0.210, 0], [0, 0.210, 0], [-0.150, 0, 0], [0.150, 0, 0]]
    np.testing.assert_allclose(feet, expected, atol=0.5 * MM)
    # The COM (body centre) projects onto edge p1-p2, strictly inside the quadrilateral 1-3-2-4.
    assert abs(feet[0, 0]) < 0.5 * MM and abs(feet[1, 0]) < 0.5 * MM
    assert feet[2, 0] < 0 < feet[3, 0]
    # The same feet from the inverse kinematics, on the branch the check lists.
    limb_points = K.body_to_limb((np.asarray(expected) - [0, 0, 0.151]) @ rot, "tetrahedron")
    solved = K.inverse_kinematics(limb_points, knee=-1)
    np.testing.assert_allclose(np.degrees(solved), np.degrees(theta), atol=0.1)


@pytest.mark.parametrize("polyhedron, n", [("tetrahedron", 4), ("octahedron", 6), ("cube", 8)])
def test_family_frames_are_proper_rotations_with_symmetric_axes(polyhedron, n):
    frames = K.limb_base_frames(polyhedron)
    assert frames.shape == (n, 4, 4) == (K.N_LIMBS[polyhedron], 4, 4)
    rot = frames[:, :3, :3]
    np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rot), 1, atol=1e-12)
    np.testing.assert_allclose(frames[:, :3, 3], 0)
    d = K.limb_directions(polyhedron)
    np.testing.assert_allclose(d.sum(axis=0), 0, atol=1e-12)
    nearest = np.sort(np.degrees(np.arccos(np.clip(d @ d.T, -1, 1))), axis=1)[:, 1]
    expected = {"tetrahedron": 109.4712, "octahedron": 90.0, "cube": 70.5288}[polyhedron]
    np.testing.assert_allclose(nearest, expected, atol=1e-3)
    # Body-frame feet back into each limb frame round-trip.
    theta = _random_theta(np.random.default_rng(RNG_SEED), n)
    feet = K.foot_in_body(theta, polyhedron=polyhedron)
    np.testing.assert_allclose(K.body_to_limb(feet, polyhedron), K.forward_kinematics(theta), atol=1e-12)


def test_cube_beast_keeps_table2_for_limbs_1_to_4_and_fills_the_control_faces():
    d = K.limb_directions("cube")
    np.testing.assert_allclose(d[:4], K.limb_directions("tetrahedron"), atol=1e-15)
    np.testing.assert_allclose(np.sort(d[4:], axis=0), np.sort(-d[:4], axis=0), atol=1e-12)


def test_bad_arguments_raise_value_error_naming_them():
    with pytest.raises(ValueError, match="polyhedron"):
        K.limb_base_frames("dodecahedron")
    with pytest.raises(ValueError, match="theta"):
        K.forward_kinematics(np.zeros(2))
    with pytest.raises(ValueError, match="theta"):
        K.foot_in_body(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="knee"):
        K.inverse_kinematics(np.array([0.2, 0, 0.1]), knee=0)
    with pytest.raises(ValueError, match="p must"):
        K.inverse_kinematics(np.zeros(2))
