"""Range-finder model (paper eq. 6), wall identification (eqs. 1-4) and the tipping noise model."""

from __future__ import annotations

import numpy as np
import pytest

from polyenvs.buckybot import geometry as geo
from polyenvs.buckybot.analysis import PAPER_MONTE_CARLO, dead_reckoning_monte_carlo
from polyenvs.buckybot.sensors import (
    RANGE_MAX_CM,
    RANGE_MIN_CM,
    RANGE_QUANTUM_CM,
    horizontal_range,
    measure_ranges,
    wall_from_pair,
)
from polyenvs.buckybot.simulator import BuckybotSimulator, TipModel
from polyenvs.core.geometry2d import SegmentTable


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


def test_horizontal_conversion():
    # (reading + 11.95) cos 19.47°: a beam's hit point measured from the robot's centre.
    assert horizontal_range(100.0) == pytest.approx((100.0 + 11.95) * np.cos(np.arcsin(1 / 3)))


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


def test_slant_vs_horizontal_matters():
    """Feeding raw slant ranges into Heron's formula is off by 6-10 percent (the spec's warning)."""
    phi = np.radians(44.4775)
    d, delta = 80.0, np.radians(10.0)
    horizontal = np.array([d / np.cos(delta + phi / 2), d / np.cos(delta - phi / 2)])
    slant = horizontal / np.cos(geo.SENSOR_ELEVATION_RAD) - geo.HEXAGON_INRADIUS_CM
    assert wall_from_pair(*horizontal_range(slant), phi)[0] == pytest.approx(80.0, abs=1e-9)
    error = abs(wall_from_pair(*slant, phi)[0] - 80.0) / 80.0
    assert 0.06 <= error <= 0.10


def _open_space_sim(n, model):
    sim = BuckybotSimulator(n, model, range_noise_scale=0.0, body_radius_cm=13.0)
    sim.set_walls(SegmentTable(np.array([[1e7, -1.0, 1e7, 1.0]])))
    sim.place(slice(None), np.zeros(2), 0, 0.0)
    sim.tip_allowed[:] = True
    return sim


def test_tipping_noise_matches_the_vicon_statistics():
    n = 100_000
    sim = _open_space_sim(n, TipModel())
    rng = np.random.default_rng(2)
    sim.tip(np.zeros(n, dtype=np.int64), rng.standard_normal((n, 3)))  # tip direction 0 = +x (heading 0)
    forward, left = sim.position[:, 0], sim.position[:, 1]
    assert forward.mean() == pytest.approx(9.266, abs=0.002)
    assert forward.std() == pytest.approx(0.105, rel=0.02)
    assert -left.mean() == pytest.approx(-0.745, abs=0.002)  # +x of the paper's frame is to the right
    assert left.std() == pytest.approx(0.149, rel=0.02)
    turn = np.degrees(sim.heading - np.pi)
    assert turn.mean() == pytest.approx(0.31, abs=0.01)
    assert turn.std() == pytest.approx(0.44, rel=0.02)
    assert abs(np.corrcoef([forward, left, turn])[np.triu_indices(3, 1)]).max() < 0.02  # uncorrelated


def test_noise_scale_zero_is_the_ideal_lattice():
    sim = _open_space_sim(10, TipModel().scaled(0.0))
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
        n_runs=4000, n_tips=100, walk="zigzag", tip_model=TipModel(heading_sd_deg=1.15), seed=0
    )
    assert matched.heading_sd_deg == pytest.approx(PAPER_MONTE_CARLO[1], rel=0.05)
    assert matched.position_sd_cm == pytest.approx(PAPER_MONTE_CARLO[0], rel=0.08)
