"""Range-finder model (paper eq. 6), wall identification (eqs. 1-4) and the tipping noise model."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import polyenvs  # noqa: F401  (registers the environments)
from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.analysis import PAPER_MONTE_CARLO, dead_reckoning_monte_carlo
from polyenvs.buckybot.env import ground_truth_parts
from polyenvs.buckybot.sensors import (
    RANGE_MAX_CM,
    RANGE_MIN_CM,
    RANGE_QUANTUM_CM,
    horizontal_range,
    measure_ranges,
    wall_from_pair,
)
from polyenvs.buckybot.simulator import BuckybotParams, BuckybotSimulator
from polyenvs.core.floor_plan import polygon_walls, rectangle_walls
from polyenvs.core.geometry2d import SegmentTable


def truth(info: dict) -> dict:
    """The named parts of ``info["ground_truth"]``."""
    return ground_truth_parts(info["ground_truth"])


def test_noise_model_mean_and_sd():
    rng = np.random.default_rng(0)
    for d in (40.0, 100.0, 170.0):
        reading, *_ = measure_ranges(np.full(200_000, d), rng.standard_normal(200_000))
        sigma = 0.013 * d + 0.448  # eq. 6
        # Rounding to 2.54 cm adds a uniform error of sd 2.54 / sqrt(12) = 0.733 cm.
        expected_sd = np.hypot(sigma, RANGE_QUANTUM_CM / np.sqrt(12))
        assert reading.mean() == pytest.approx(d, abs=0.05)
        assert reading.std() == pytest.approx(expected_sd, rel=0.05)


def test_quantisation_and_the_two_invalid_cases():
    true = np.array([20.0, 30.48, 31.0, 100.0, 182.88, 190.0, np.inf])
    reading, too_close, no_return = measure_ranges(true, np.zeros_like(true))
    np.testing.assert_array_equal(too_close, [True, False, False, False, False, False, False])
    np.testing.assert_array_equal(no_return, [False, False, False, False, False, True, True])
    valid = ~(too_close | no_return)
    assert np.allclose(np.round(reading[valid] / RANGE_QUANTUM_CM), reading[valid] / RANGE_QUANTUM_CM)
    assert reading[1] == pytest.approx(RANGE_MIN_CM) and reading[4] == pytest.approx(RANGE_MAX_CM)
    assert np.isnan(reading[~valid]).all()


@pytest.mark.parametrize("phi_deg", [44.4775, 75.5225])
def test_heron_distance_and_inclination_on_synthetic_walls(phi_deg):
    rng = np.random.default_rng(1)
    phi = np.radians(phi_deg)
    for _ in range(500):
        d = rng.uniform(30, 150)
        # Wall normal anywhere the two beams both hit the wall in front of them.
        delta = rng.uniform(-(np.pi / 2 - phi / 2) + 0.05, (np.pi / 2 - phi / 2) - 0.05)
        x = d / np.cos(delta + phi / 2)  # first beam at -phi/2 from the bisector
        y = d / np.cos(delta - phi / 2)
        d_est, delta_est = wall_from_pair(x, y, phi)
        assert d_est == pytest.approx(d, abs=1e-9)
        assert delta_est == pytest.approx(delta, abs=1e-9)


# The sonar model is checked against geometry written out here: a 3-D beam leaving the centre of an upper hexagon
# (11.95 cm from the body centre along the face normal, 19.47° = asin(1/3) above the horizon) meets vertical walls.
_ELEVATION = np.arcsin(1.0 / 3.0)
_ROOM = polygon_walls((0, 0), (520, 0), (520, 210), (330, 360), (0, 360))  # one wall runs diagonally
_PILLAR = rectangle_walls(380, 60, 420, 100)


def _cast(x, y, heading, segments):
    """Slant distance from each upper sensor along its beam to the first wall, and the hit points (x, y)."""
    az = heading + geo.SENSOR_AZIMUTHS_RAD
    n = np.cos(_ELEVATION) * np.stack([np.cos(az), np.sin(az)], axis=-1)  # horizontal part of the unit beam
    sensor = np.array([x, y]) + 11.95 * n
    best = np.full(6, np.inf)
    for x1, y1, x2, y2 in segments:
        wall = np.array([x2 - x1, y2 - y1])
        for i in range(6):
            # sensor + t n = (x1, y1) + u wall, for the slant distance t along the beam and u along the wall
            m = np.array([n[i], -wall]).T
            if abs(np.linalg.det(m)) < 1e-12:
                continue
            t, u = np.linalg.solve(m, np.array([x1, y1]) - sensor[i])
            if t >= 0 and 0 <= u <= 1:
                best[i] = min(best[i], t)
    return best, sensor + best[:, None] * n


def _place(pose, segments, face=1):
    env = gym.make("polyenvs/BuckybotWallFollow-v0", floor_plan=segments, range_noise_scale=0.0)
    obs, info = env.reset(seed=0, options={"pose": pose, "face": face})
    structure = env.unwrapped.observation_structure
    env.close()
    part = {name: obs[slice(*structure[name])] for name in ("range", "too_close", "no_return")}
    return part, info


def test_ranges_are_slant_distances_along_the_tilted_beams():
    """True ranges and readings against rays cast here, from random poses on many faces; all three outcomes occur."""
    rng = np.random.default_rng(4)
    segments = _ROOM + _PILLAR
    poses = [(25.0, 180.0, 170.0), (495.0, 30.0, 12.0), (200.0, 300.0, 95.0)]  # hugging walls: too-close beams
    poses += [(rng.uniform(60, 300), rng.uniform(60, 300), rng.uniform(0, 360)) for _ in range(12)]
    outcomes = set()
    for k, pose in enumerate(poses):
        part, info = _place(pose, segments, face=1 + k % 20)
        slant, _ = _cast(pose[0], pose[1], np.radians(pose[2]), segments)
        np.testing.assert_allclose(truth(info)["true_range_cm"], slant, rtol=1e-9)
        expected = np.round(slant / RANGE_QUANTUM_CM) * RANGE_QUANTUM_CM  # noiseless, whole inches
        too_close, no_return = expected < RANGE_MIN_CM - 1e-6, ~(expected <= RANGE_MAX_CM + 1e-6)
        np.testing.assert_array_equal(part["too_close"] > 0.5, too_close)
        np.testing.assert_array_equal(part["no_return"] > 0.5, no_return)
        valid = ~(too_close | no_return)
        np.testing.assert_allclose(part["range"][valid] * RANGE_MAX_CM, expected[valid], atol=1e-3)
        outcomes |= {"too_close"} if too_close.any() else set()
        outcomes |= {"no_return"} if no_return.any() else set()
        outcomes |= {"valid"} if valid.any() else set()
    assert outcomes == {"too_close", "no_return", "valid"}


def test_horizontal_range_and_heron_need_the_beam_tilt():
    """Facing a wall 80 cm away, 10° off its normal, with the 44.48° pair: the readings converted to horizontal
    distances place the hits and the wall; raw slant readings put the wall 6 to 10 percent off (the spec's warning)."""
    wall_y, centre = 300.0, np.array([250.0, 220.0])
    segments = rectangle_walls(0, 0, 500, wall_y)
    heading = 90.0 + 10.0  # frame direction 0 bisects sensors 5 (-22.24°) and 0 (+22.24°)
    part, _ = _place((*centre, heading), segments)
    reading = part["range"][[5, 0]].astype(np.float64) * RANGE_MAX_CM
    slant, hits = _cast(*centre, np.radians(heading), segments)
    np.testing.assert_allclose(reading, slant[[5, 0]], atol=RANGE_QUANTUM_CM / 2 + 1e-3)
    # A hit's horizontal distance from the centre, within the reading's half-inch rounding.
    true_horizontal = np.hypot(*(hits[[5, 0]] - centre).T)
    np.testing.assert_allclose(horizontal_range(reading), true_horizontal, atol=RANGE_QUANTUM_CM / 2 + 1e-3)
    phi = geo.SENSOR_AZIMUTHS_RAD[0] - (geo.SENSOR_AZIMUTHS_RAD[5] - 2 * np.pi)
    d, delta = wall_from_pair(*horizontal_range(reading), phi)
    assert d == pytest.approx(wall_y - centre[1], abs=1.5)
    assert np.degrees(delta) == pytest.approx(-10.0, abs=1.5)  # the normal is 10° clockwise of the bisector
    error = abs(wall_from_pair(*reading, phi)[0] - 80.0) / 80.0
    assert 0.06 <= error <= 0.10


def _open_space_sim(n, robot, heading=0.0):
    sim = BuckybotSimulator(n, robot)
    sim.set_walls(SegmentTable(np.array([[1e7, -1.0, 1e7, 1.0]])))  # one wall far away: no tip is blocked
    sim.place(slice(None), np.zeros(2), 0, heading)
    return sim


@pytest.mark.parametrize("direction", [0, 1, 2])
def test_tipping_noise_matches_the_vicon_statistics(direction):
    """Each tip, at random headings, in the tip's own frame: 9.266 ± 0.105 cm forward, -0.745 ± 0.149 cm to the
    right (the paper's +x, with +y the tip direction and +z up), a turn of 0.31 ± 0.44° on top of the frame's
    120° j + 180°, uncorrelated."""
    n = 60_000
    rng = np.random.default_rng(2 + direction)
    heading = rng.uniform(0, 2 * np.pi, n)
    sim = _open_space_sim(n, BuckybotParams(), heading)
    sim.tip(np.full(n, direction, dtype=np.int64), rng.standard_normal((n, 3)))
    along = heading + np.radians(120.0 * direction)
    forward = sim.position[:, 0] * np.cos(along) + sim.position[:, 1] * np.sin(along)
    right = sim.position[:, 0] * np.sin(along) - sim.position[:, 1] * np.cos(along)
    assert forward.mean() == pytest.approx(9.266, abs=0.003)
    assert forward.std() == pytest.approx(0.105, rel=0.03)
    assert right.mean() == pytest.approx(-0.745, abs=0.003)
    assert right.std() == pytest.approx(0.149, rel=0.03)
    # The frame itself turns by 120° j + 180° (``along`` + 180°); what is left, wrapped to +-180°, is the noise.
    turn = np.degrees((sim.heading - along) % (2 * np.pi) - np.pi)
    assert turn.mean() == pytest.approx(0.31, abs=0.01)
    assert turn.std() == pytest.approx(0.44, rel=0.03)
    assert abs(np.corrcoef([forward, right, turn])[np.triu_indices(3, 1)]).max() < 0.03  # uncorrelated


def test_noise_scale_zero_is_the_ideal_lattice():
    sim = _open_space_sim(10, BuckybotParams(noise_scale=0.0))
    sim.tip(np.ones(10, dtype=np.int64), np.random.default_rng(3).standard_normal((10, 3)))
    np.testing.assert_allclose(np.hypot(*sim.position.T), geo.STEP_LENGTH_CM)
    np.testing.assert_allclose(np.degrees(np.arctan2(sim.position[:, 1], sim.position[:, 0])), 120.0)


def test_monte_carlo_after_100_tips_next_to_the_paper():
    """The paper: 90.42 cm and 11.5° after 100 tips. The stated per-tip model cannot give that (spec A3).

    With the paper's 0.44°/tip heading sd, a straight-ish (zig-zag) walk gives ~35 cm and 0.44 sqrt(100) = 4.4°;
    the paper's pair is reproduced only with ~1.15°/tip (90.7 cm, 11.4° in the spec's check). Both are recorded.
    """
    stated = dead_reckoning_monte_carlo(n_runs=4000, n_tips=100, walk="zigzag", seed=0)
    assert stated.distance_travelled_cm == pytest.approx(929.6, abs=1.0)  # the paper's "roughly 929 cm"
    assert stated.heading_sd_deg == pytest.approx(4.4, rel=0.05)
    assert stated.position_sd_cm == pytest.approx(35.1, rel=0.08)
    assert stated.position_sd_cm < 0.5 * PAPER_MONTE_CARLO[0]  # not the paper's number, and we say so
    matched = dead_reckoning_monte_carlo(
        n_runs=4000, n_tips=100, walk="zigzag", robot=BuckybotParams(heading_sd_deg=1.15), seed=0
    )
    assert matched.heading_sd_deg == pytest.approx(PAPER_MONTE_CARLO[1], rel=0.05)
    assert matched.position_sd_cm == pytest.approx(PAPER_MONTE_CARLO[0], rel=0.08)
