"""The bumper cart's odometry, maps and closed-form cycle simulator against brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest

from polyenvs.bumper import cart as C
from polyenvs.bumper.maps import MAPS, BumperMap, make_map
from polyenvs.bumper.odometry import TICK_CM, dead_reckon, odometry_step


def _integrate(a, b, d, n=20000):
    """Differential-drive kinematics integrated in small steps (the reference for the closed form)."""
    x = y = h = 0.0
    da, db = a / n, b / n
    for _ in range(n):
        h_mid = h + 0.5 * (db - da) / d
        x += 0.5 * (da + db) * math.cos(h_mid)
        y += 0.5 * (da + db) * math.sin(h_mid)
        h += (db - da) / d
    return x, y, h


# --- odometry --------------------------------------------------------------------------------------------------


def test_tick_is_the_papers_0_0675_inch():
    assert TICK_CM == pytest.approx(0.171450)


@pytest.mark.parametrize("a,b", [(10.0, 12.0), (30.0, -5.0), (-8.0, -6.0), (5.0, -5.0), (20.0, 20.0), (-3.0, 40.0)])
def test_odometry_matches_integrated_kinematics(a, b):
    d = 6.0
    ref = _integrate(a, b, d)
    got = odometry_step(0.0, 0.0, 0.0, a, b, d)
    np.testing.assert_allclose(got, ref, atol=1e-6)


def test_odometry_straight_spin_and_radius_form():
    assert odometry_step(0, 0, 0, 12.5, 12.5, 6.0) == pytest.approx((12.5, 0.0, 0.0))
    x, y, h = odometry_step(0, 0, 0, -3.0, 3.0, 6.0)  # spin in place: 2b/d
    assert (x, y, h) == pytest.approx((0.0, 0.0, 1.0))
    a, b, d = 10.0, 14.0, 6.0  # the paper's r, θ form where it is regular
    theta, r = (b - a) / d, d * (a + b) / (2 * (b - a))
    assert odometry_step(0, 0, 0, a, b, d) == pytest.approx((r * math.sin(theta), r * (1 - math.cos(theta)), theta))


def test_wheel_base_sensitivity_of_a_right_angle():
    """A 5% wheel-base error turns a 90° spin into a 4.3° heading error (spec, section D)."""
    d = 6.0
    spin = math.pi / 2 * d / 2
    _, _, h = odometry_step(0, 0, 0, -spin, spin, d * 1.05)
    assert math.degrees(math.pi / 2 - h) == pytest.approx(4.29, abs=0.01)


def test_dead_reckon_adds_stages_end_to_end():
    ticks = np.array([[-20, 20], [300, 305], [-35, -35]])
    poses = dead_reckon((10.0, 5.0, 0.3), ticks, 6.0)
    x, y, h = 10.0, 5.0, 0.3
    for left, right in ticks:
        x, y, h = odometry_step(x, y, h, left * TICK_CM, right * TICK_CM, 6.0)
    np.testing.assert_allclose(poses[-1], (x, y, h))
    assert poses.shape == (4, 3)


# --- maps ------------------------------------------------------------------------------------------------------


def test_builtin_maps_are_valid_and_fit_the_cart():
    radius = C.CartModel().circumradius_cm
    for name in MAPS:
        world = make_map(name, clearance_cm=radius + 1)
        assert world.wall_length_cm > 0
    paper = make_map("paper")
    assert paper.bounds == (0.0, 0.0, 120.0, 90.0)
    assert paper.free(np.array([[60.0, 45.0], [5.0, 85.0], [130.0, 45.0]])).tolist() == [True, False, False]
    maze = make_map("maze")
    assert not maze.free(np.array([51.0, 80.0]))  # inside an interior wall


@pytest.mark.parametrize(
    "polygons,match",
    [
        ("nowhere", "map must be one of"),
        ([[(0, 0), (1, 1)]], "at least 3"),
        ([[(0, 0), (100, 0), (0, 100), (100, 100)]], "intersect"),
        ([[(0, 0), (100, 0), (100, float("nan"))]], "finite"),
        ([[(0, 0), (100, 0), (100, 100), (0, 100)], [(200, 200), (210, 200), (210, 210)]], "inside the outline"),
        ([[(0, 0), (100, 0), (100, 100), (0, 100)], [(-10, 50), (50, 40), (50, 60)]], "intersect"),
        ([[(0, 0), (5000, 0), (5000, 10), (0, 10)]], "at most"),
        ([[(0, 0), (100, 0), (100.1, 0), (100, 100)]], "at least 0.5"),
        ([[(0, 0), (8, 0), (8, 8), (0, 8)]], "does not fit"),
        ([[(0, 0), (100, 0), (100, 100), (0, 100)], [(10, 10), (90, 10), (90, 90)], [(40, 30), (60, 30), (60, 40)]],
         "contain one another"),
    ],
)  # fmt: skip
def test_bad_maps_raise(polygons, match):
    with pytest.raises(ValueError, match=match):
        make_map(polygons, clearance_cm=C.CartModel().circumradius_cm + 1)


def test_user_map_as_one_polygon_and_wall_cells():
    world = make_map([(0, 0), (100, 0), (100, 50), (0, 50)])
    assert isinstance(world, BumperMap) and len(world.segments) == 4
    first, counts, lengths = world.wall_cells(5.0)
    assert counts.tolist() == [20, 10, 20, 10] and first.tolist() == [0, 20, 30, 50]
    assert lengths.sum() == pytest.approx(300.0)


# --- the closed-form cycle -------------------------------------------------------------------------------------


def _body(x, y, h, model):
    c, s = math.cos(h), math.sin(h)
    half = model.bumper_width_cm / 2
    local = [(model.bumper_offset_cm, -half), (model.bumper_offset_cm, half), (-model.rear_cm, half),
             (-model.rear_cm, -half)]  # fmt: skip
    return np.array([(x + lx * c - ly * s, y + lx * s + ly * c) for lx, ly in local])


def _overlaps(body, world):
    """Brute force: does the body rectangle intersect a wall (edges cross, or a wall vertex inside the body)?"""
    from polyenvs.bumper.maps import _segments_cross

    edges = np.concatenate([body, np.roll(body, -1, axis=0)], axis=1)
    if _segments_cross(edges, world.segments).any():
        return True
    return not world.free(body).all()


def _params(model, **over):
    return C.CartModel(**{**model.as_dict(), **over}).packed()


def test_head_on_drive_stops_at_the_wall():
    model = C.CartModel()
    world = make_map("rectangle")
    row = np.zeros(C.N_STATE)
    C.place_row(row, (60.0, 45.0, 0.0), 0.0, model.wheel_base_cm)
    params = _params(model, slip_sd=0.0, snap_prob=0.0, slide_prob=0.0)
    C.cycle_row(row, 0.0, np.zeros(C.DRAWS_PER_CYCLE), params, world.walls)
    assert row[C.BUMP] == 1.0
    assert row[C.BUMP_X] + model.bumper_offset_cm == pytest.approx(120.0, abs=1e-5)
    assert row[C.TICKS + 2] == round(53.0 / TICK_CM) == row[C.TICKS + 3]
    assert row[C.TICKS + 4] == row[C.TICKS + 5] == -35  # the back-up: 6 cm
    assert row[C.CONTACT_X] == pytest.approx(120.0)
    assert row[C.X] == pytest.approx(120.0 - model.bumper_offset_cm - 6.0, abs=1e-5)


@pytest.mark.parametrize("name", ["paper", "maze", "obstacles"])
def test_contacts_agree_with_brute_force(name):
    """First contact of random arcs, lines and spins: free just before, overlapping just after."""
    model = C.CartModel()
    params = model.packed()
    world = make_map(name)
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(150):
        x, y, h = world.sample_pose(rng, model.circumradius_cm + 0.2)
        kind = rng.integers(3)
        if kind == 0:
            a = 200.0 * rng.random() * rng.choice([-1, 1])
            b = a * (1 + 0.3 * rng.standard_normal())
        elif kind == 1:
            a = b = 150.0 * rng.choice([-1, 1])
        else:
            b = 12.0 * rng.standard_normal()
            a = -b * (1 + 0.05 * rng.standard_normal())
        d = model.wheel_base_cm
        theta = (b - a) / d
        pieces = max(1, math.ceil(abs(theta) / (math.pi / 2)))
        t, seg, cx, cy = C._first_contact(x, y, h, a / pieces, b / pieces, d, params, world.walls)
        if seg < 0:
            t = 1.0
        for s in np.linspace(0, t, 40)[:-1]:
            assert not _overlaps(_body(*odometry_step(x, y, h, s * a / pieces, s * b / pieces, d), model), world)
        if seg >= 0:
            checked += 1
            after = min(t + 1e-3, 1.0)
            assert _overlaps(_body(*odometry_step(x, y, h, after * a / pieces, after * b / pieces, d), model), world)
            assert world.clearance(np.array([cx, cy])) == pytest.approx(0.0, abs=1e-6)
    assert checked > 50


def _every_candidate_contact(x, y, h, a, b, d, params, walls):
    """The contact search without its shortcuts: every body corner against every wall, then every wall's start
    vertex against every body edge, each crossing solved over the whole motion; the earliest wins, a tie the first."""
    theta, s = (b - a) / d, 0.5 * (a + b)
    c, sn = math.cos(h), math.sin(h)
    corners = [(params[C.P_FRONT], -params[C.P_HALF]), (params[C.P_FRONT], params[C.P_HALF]),
               (-params[C.P_REAR], params[C.P_HALF]), (-params[C.P_REAR], -params[C.P_HALF])]  # fmt: skip
    best, seg, cx, cy = math.inf, -1, 0.0, 0.0
    for lx, ly in corners:
        px, py = x + lx * c - ly * sn, y + lx * sn + ly * c
        wx, wy = theta * (px - x) + s * sn, theta * (py - y) - s * c
        for k, wall in enumerate(walls):
            if wall[5] != 0.0:
                t = C._crossing((px, py), (wx, wy), theta, tuple(wall[:4]), wall[5], 1.0)
                if t < best:
                    sa = t if theta == 0.0 else math.sin(t * theta) / theta
                    ka = 0.0 if theta == 0.0 else (1.0 - math.cos(t * theta)) / theta
                    best, seg, cx, cy = t, k, px - sa * wy - ka * wx, py + sa * wx - ka * wy
    for k, wall in enumerate(walls):
        if wall[5] == 0.0:
            continue
        vx, vy = wall[0], wall[1]
        wx, wy = -theta * (vx - x) - s * sn, -theta * (vy - y) + s * c
        for i in range(4):
            (l0x, l0y), (l1x, l1y) = corners[i], corners[(i + 1) % 4]
            rx, ry = x + l0x * c - l0y * sn, y + l0x * sn + l0y * c
            ex, ey = (l1x - l0x) * c - (l1y - l0y) * sn, (l1x - l0x) * sn + (l1y - l0y) * c
            outward = math.copysign(1.0, ey * (x - rx) - ex * (y - ry))
            t = C._crossing((vx, vy), (wx, wy), -theta, (rx, ry, ex, ey), outward, 1.0)
            if t < best:
                best, seg, cx, cy = t, k, vx, vy
    return best, seg, cx, cy


#: A round room of 100 walls: past the 64 whose nearness the contact search keeps in a bit mask.
_ROUND_ROOM = [[(80.0 + 70.0 * math.cos(2 * math.pi * i / 100), 80.0 + 70.0 * math.sin(2 * math.pi * i / 100))
                for i in range(100)]]  # fmt: skip


@pytest.mark.parametrize("name", [*sorted(MAPS), "round"])
def test_contact_search_shortcuts_change_nothing(name):
    # The search skips walls out of reach and solves each crossing only up to the earliest contact found so far;
    # from the poses a random bounce visits (many of them touching a wall), every stage's motion must give the
    # exhaustive search's contact bit for bit.
    model = C.CartModel(mismatch_sd=0.05, snap_prob=0.5, slide_prob=0.5)
    world = make_map(_ROUND_ROOM if name == "round" else name)
    params, rng = model.packed(), np.random.default_rng(11)
    row = np.zeros(C.N_STATE)
    C.place_row(row, world.sample_pose(rng, model.circumradius_cm + 0.5), *model.draw_episode(rng))
    contacts = 0
    for _ in range(150):
        C.cycle_row(row, rng.uniform(-math.pi, math.pi), rng.standard_normal(C.DRAWS_PER_CYCLE), params, world.walls)
        for a, b in ((300.0, 300.0 * (1 + 0.05 * rng.standard_normal())), (-6.0, -6.2), (-4.0, 4.5), (9.0, -8.7)):
            motion = (row[C.X], row[C.Y], row[C.HEADING], a, b, row[C.BASE], params, world.walls)
            got = C._first_contact(*motion)
            want = _every_candidate_contact(*motion)
            assert np.array(got).tobytes() == np.array(want).tobytes(), (motion[:6], got, want)
            contacts += got[1] >= 0
    assert contacts > 150


@pytest.mark.parametrize("name", sorted(MAPS))
def test_long_random_bounce_never_enters_a_wall(name):
    model = C.CartModel(snap_prob=0.5, slide_prob=0.5)
    params = model.packed()
    world = make_map(name)
    rng = np.random.default_rng(7)
    row = np.zeros(C.N_STATE)
    C.place_row(row, world.sample_pose(rng, model.circumradius_cm + 0.5), *model.draw_episode(rng))
    bumps = 0
    for _ in range(400):
        C.cycle_row(row, rng.uniform(-math.pi, math.pi), rng.standard_normal(C.DRAWS_PER_CYCLE), params, world.walls)
        assert not _overlaps(_body(row[C.X], row[C.Y], row[C.HEADING], model), world)
        assert world.clearance(row[[C.X, C.Y]]) > 0
        bumps += row[C.BUMP]
        ticks = row[C.TICKS : C.TICKS + 6]
        assert (ticks == np.rint(ticks)).all() and np.abs(ticks).max() <= C.max_ticks(model)
    assert bumps > 300


def test_dead_reckoning_is_exact_without_noise_and_drifts_with_it():
    world = make_map("paper")
    start = np.array([60.0, 40.0, 0.5])
    turns = np.random.default_rng(3).uniform(-math.pi, math.pi, 30)
    errors = []
    for model in (C.CartModel(mismatch_sd=0, wheel_base_sd=0, slip_sd=0, snap_prob=0, slide_prob=0), C.CartModel()):
        row = np.zeros(C.N_STATE)
        C.place_row(row, start, *model.draw_episode(np.random.default_rng(4)))
        draws = np.random.default_rng(5).standard_normal((30, C.DRAWS_PER_CYCLE))
        for turn, z in zip(turns, draws, strict=True):
            C.cycle_row(row, turn, z, model.packed(), world.walls)
        errors.append(math.hypot(row[C.X] - row[C.DR_X], row[C.Y] - row[C.DR_Y]))
    assert errors[0] < 3.0  # only the ticks' rounding (half a tick of wheel difference is 0.8° of heading)
    assert errors[1] > 3 * errors[0], errors


@pytest.mark.parametrize(
    "name,value",
    [("wheel_base_cm", 7.0), ("wheel_base_cm", True), ("slip_sd", -0.1), ("backup_cm", float("nan")),
     ("snap_prob", "0.3"), ("max_drive_cm", 1e5)],
)  # fmt: skip
def test_bad_cart_parameters_name_themselves(name, value):
    with pytest.raises(ValueError, match=name):
        C.CartModel(**{name: value})
