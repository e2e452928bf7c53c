"""The Buckybot paper's remaining claims (``seeds/000``): the body that blocks a tip, the lower sensors that see the
floor, the 80 cm walls that the longest reading needs, and the lone reading that is an object, not a wall.

The geometry is worked out here from the solid (``_truncated_icosahedron``, checked against the paper's sizes in
``test_buckybot_geometry.py``) and from the beam's height and tilt, not read off the simulator's constants."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the environments)
from baselines.buckybot import WallFollower, decode_readings
from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.env import ground_truth_parts
from polyenvs.buckybot.sensors import measure_ranges, walls_from_readings
from polyenvs.core.floor_plan import rectangle_walls
from tests.test_buckybot_geometry import _axis_rotation, _truncated_icosahedron

WALL_FOLLOW = "polyenvs/BuckybotWallFollow-v0"
#: Half the 23.9 cm between opposite hexagons (paper, "Actuation and Control"): the centre's height, and the
#: distance from the centre to each hexagon's sensor.
INRADIUS_CM = 23.9 / 2
#: The side sensors' tilt above or below the horizon, asin(1/3) = 19.47° (paper, "Geometry and Sensing").
TILT = np.arcsin(1.0 / 3.0)


def _wall_follow(floor_plan, **kwargs) -> gym.Env:
    """BuckybotWallFollow-v0 on ``floor_plan`` with noiseless readings."""
    return gym.make(WALL_FOLLOW, floor_plan=floor_plan, range_noise_scale=0.0, **kwargs)


def _place(env: gym.Env, pose, face: int = 1) -> tuple[np.ndarray, dict]:
    return env.reset(seed=0, options={"pose": pose, "face": face})


# --- the blocked-tip model: the body, 26.0 cm across, may not touch a wall -----------------------------------------
def _horizontal_reach(corners: np.ndarray, azimuths: np.ndarray) -> np.ndarray:
    """How far the body reaches from its vertical axis towards each azimuth (its support function); ``corners``
    ``(..., 60, 3)``, the result ``(..., len(azimuths))``."""
    return (corners[..., :2] @ np.stack([np.cos(azimuths), np.sin(azimuths)])).max(axis=-2)


def _resting_corners() -> np.ndarray:
    """``(20, 60, 3)``: the solid's corners (cm) resting on each face, centre at the origin, floor at z = -11.95,
    tip direction 0 along +x."""
    return _truncated_icosahedron() @ geo.face_frames().transpose(0, 2, 1)


def _rolled(corners: np.ndarray, angle: float) -> np.ndarray:
    """``corners`` rolled by ``angle`` over tip edge 0: the floor edge farthest along +x."""
    on_floor = np.isclose(corners[:, 2], -INRADIUS_CM)
    pivot = corners[on_floor & np.isclose(corners[:, 0], corners[on_floor, 0].max())][0]
    return (corners - pivot) @ _axis_rotation([0, 1, 0], angle).T + pivot


def test_a_tip_that_would_make_the_body_touch_a_wall_is_blocked():
    """The paper's body is 26.0 cm across. Resting on any face the solid reaches 12.77 to 13.03 cm from its vertical
    axis, depending on the direction, and while it rolls over the tip edge every point moves forward, so the body
    reaches farthest at the landing: checking the landing is checking the tip. The environment (ideal lattice)
    blocks every tip whose landing leaves a wall closer than the solid's least reach, and allows every tip whose
    landing leaves it farther than its greatest reach, whatever the angle between the tip and the wall."""
    resting = _resting_corners()
    reach = _horizontal_reach(resting, np.radians(np.arange(0.0, 360.0, 0.05)))
    least, greatest = reach.min(), reach.max()
    assert least == pytest.approx(12.77, abs=0.005) and greatest == pytest.approx(13.03, abs=0.005)
    assert 2 * least < 26.0 < 2 * greatest  # the paper's diameter, within the solid's own spread

    body = np.vstack([resting[0], np.zeros(3)])  # face 1's corners, and its centre last
    roll = np.array([_rolled(body, a) for a in np.linspace(0.0, geo.DIHEDRAL_TIP_RAD, 100)])
    assert np.isclose(roll[-1, :, 2], -INRADIUS_CM).sum() == 6  # landed flat on the next hexagon
    step = np.hypot(*roll[-1, -1, :2])
    assert step == pytest.approx(9.129, abs=5e-4)
    during = _horizontal_reach(roll, np.radians(np.arange(-89.0, 90.0)))  # towards any wall ahead
    np.testing.assert_allclose(during.max(axis=0), during[-1], atol=1e-9)

    env = _wall_follow(rectangle_walls(0, 0, 400, 300), noise_scale=0.0)
    for k, angle in enumerate((-60.0, -30.0, 0.0, 30.0, 60.0)):  # between tip 0 and the east wall's normal
        for gap, blocked in (
            (least - 1.0, True),
            (least - 0.05, True),
            (greatest + 0.05, False),
            (greatest + 1.0, False),
        ):
            start = gap + step * np.cos(np.radians(angle))  # from the east wall: the landing is ``gap`` from it
            _, info = _place(env, (400.0 - start, 150.0, angle), face=1 + 4 * k)
            assert info["action_mask"][0] == (not blocked), (angle, gap)


# --- the lower sensors see the floor at about 23 cm -----------------------------------------------------------------
def test_the_lower_sensors_see_the_floor_within_the_sonars_dead_zone():
    """Paper: the six sensors 19.47° below the horizon have "a visibility of only about 23.0 cm (9 in.) before the
    sensor picks up the floor", so only the upper six are used. From any resting face, the six faces at -19.47°
    carry sensors 7.97 cm above the floor, whose beams meet it 23.90 cm away (22.53 cm horizontally), both within
    an inch of the paper's 23.0 cm; and that is inside the sonar's 30.48 cm dead zone: with eq. 6's noise, 100,000
    readings of the floor are all "too close", never a range."""
    normals = geo.FACE_NORMALS_HOME
    elevation = np.arcsin(np.clip(-normals @ normals.T, -1, 1))  # [f, g]: face g's, resting on f (f's points down)
    lower = np.isclose(elevation, -TILT)
    assert (lower.sum(axis=1) == 6).all()
    height = INRADIUS_CM * (1 + np.sin(elevation[lower]))  # the lower hexagons' centres, above the floor
    floor_range = height / np.sin(TILT)  # along the beam
    np.testing.assert_allclose(height, 7.97, atol=0.005)
    np.testing.assert_allclose(floor_range, 23.90, atol=0.005)
    np.testing.assert_allclose(floor_range * np.cos(TILT), 22.53, atol=0.005)
    assert abs(23.90 - 23.0) < 2.54 and abs(22.53 - 23.0) < 2.54  # "about 23.0 cm (9 in.)"
    rng = np.random.default_rng(0)
    reading, too_close, no_return = measure_ranges(np.full(100_000, floor_range[0]), rng.standard_normal(100_000))
    assert too_close.all() and not no_return.any() and np.isnan(reading).all()


# --- 80 cm walls are enough at the 183 cm range ---------------------------------------------------------------------
def test_80_cm_walls_are_tall_enough_for_every_valid_reading():
    """Paper: "At the maximum sensing distance, 183 cm (72 in.), walls need only be 80 cm (31.5 in.) tall". The
    upper beam leaves its sensor 15.93 cm up and climbs at 19.47°: 183 cm out from the sensor it is 80.6 cm high.
    Facing a wall with one beam (noiseless readings), the farthest wall that still gives a valid reading is 184.75
    cm from the centre; the beam meets it 77.27 cm up, and every nearer one lower, so 80 cm walls always suffice,
    while a 75 cm wall would be missed by the longest readings. Beyond that, the sensor reports no return."""
    sensor_height = INRADIUS_CM + INRADIUS_CM * np.sin(TILT)
    sensor_out = INRADIUS_CM * np.cos(TILT)  # the sensor's horizontal distance from the centre
    assert sensor_height + 183.0 * np.tan(TILT) == pytest.approx(80.0, rel=0.01)  # the paper's figure

    beam = geo.SENSOR_AZIMUTHS_RAD[0]
    distances = np.arange(160.0, 200.0, 0.25)  # from the centre to the wall, along sensor 0's beam
    env = _wall_follow(rectangle_walls(0, 0, 600, 600))
    no_return = env.unwrapped.observation_structure["no_return"][0]  # sensor 0's flag
    valid = np.array([_place(env, (600.0 - d, 300.0, -np.degrees(beam)))[0][no_return] < 0.5 for d in distances])
    assert valid[0] and not valid[-1] and (np.diff(valid.astype(int)) <= 0).all()  # valid up to a range, then not
    hit_height = sensor_height + (distances - sensor_out) * np.tan(TILT)
    assert hit_height[valid].max() == pytest.approx(77.27, abs=0.1)
    assert 75.0 < hit_height[valid].max() <= 80.0


# --- one sensor alone is an object, not a wall -------------------------------------------------------------------
#: The follower's pose: at (450, 450) facing 0°, so sensor 0 looks out at +22.24°.
LOOKOUT = (450.0, 450.0, 0.0)
#: 150 cm from the centre along sensor 0's beam.
AHEAD = np.array(LOOKOUT[:2]) + 150.0 * np.array(
    [np.cos(geo.SENSOR_AZIMUTHS_RAD[0]), np.sin(geo.SENSOR_AZIMUTHS_RAD[0])]
)


def _follower_sees(floor_plan) -> tuple[np.ndarray, np.ndarray, float]:
    """The wall follower's first decision from ``LOOKOUT``: the sensors with a valid reading, the distances of the
    walls it identifies, and how much its tip changes the robot's distance to ``AHEAD``."""
    env = _wall_follow(floor_plan)
    obs, info = _place(env, LOOKOUT)
    follower = WallFollower(env.observation_space, env.action_space)
    reading, _, _ = decode_readings(obs, follower.too_close_cm)
    distance, _ = walls_from_readings(reading)
    before = np.hypot(*(ground_truth_parts(info["ground_truth"])["pose"][:2] - AHEAD))
    *_, info = env.step(follower.act(obs, follower.initial_memory()))
    after = np.hypot(*(ground_truth_parts(info["ground_truth"])["pose"][:2] - AHEAD))
    return np.flatnonzero(~np.isnan(reading)), distance[~np.isnan(distance)], after - before


def test_one_sensor_alone_sees_an_object_not_a_wall():
    """Paper: "If only one sensor registers an obstacle, then we assumed that the sensor is picking up an object
    and not a wall." A 10 cm post 150 cm out along sensor 0's beam, in a room too large for the other beams: one
    valid reading, no wall identified, and the wall follower (d* = 50 cm) tips away from the post into open
    space. A long wall as far ahead, seen by sensors 5 and 0: a wall 150 cm away, and the follower tips towards it
    to close in on d*."""
    post = rectangle_walls(AHEAD[0], AHEAD[1] - 5.0, AHEAD[0] + 10.0, AHEAD[1] + 5.0)
    seen, walls, closer = _follower_sees(rectangle_walls(0, 0, 900, 900) + post)
    assert seen.tolist() == [0] and walls.size == 0
    assert closer > 0  # away from the object

    seen, walls, closer = _follower_sees(rectangle_walls(0, 0, LOOKOUT[0] + 150.0, 900))
    assert seen.tolist() == [0, 5] and walls == pytest.approx([150.0], abs=2.0)
    assert closer < 0  # towards the wall
