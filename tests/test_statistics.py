"""Our IQM, stratified bootstrap interval and performance profile against rliable's on the same data.

rliable (Agarwal et al. 2021) takes a ``(runs, tasks)`` score matrix and resamples runs within each task
(``StratifiedBootstrap``); ours takes groups and resamples values within each group, so its groups are the matrix's
columns. The point estimates must agree exactly; the percentile intervals within bootstrap noise (the same number of
resamples, 2000, but other random draws): a tenth of the interval's width.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from polyenvs.statistics import interquartile_mean, iqm_with_stratified_ci, mean_with_stratified_ci, performance_profile

REPS = 2000


def test_the_iqm_of_a_worked_example():
    # rliable's IQM is scipy.stats.trim_mean(x, 0.25): floor(n / 4) values cut from each end, the rest averaged.
    assert interquartile_mean(range(10)) == pytest.approx(4.5)  # 2..7
    assert interquartile_mean([0, 0, 0, 1, 1, 1, 1, 100]) == pytest.approx(0.75)  # 0, 1, 1, 1: the outlier cut


@pytest.fixture(scope="module")
def rliable():
    pytest.importorskip("rliable", reason="rliable is in the dev extra")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # arch's own FutureWarnings
        from rliable import library, metrics
    return library, metrics


@pytest.mark.parametrize("shape", [(50, 3), (10, 5), (51, 1)], ids=lambda s: f"{s[0]}runs x {s[1]}tasks")
def test_iqm_and_its_stratified_interval_match_rliable(rliable, shape):
    library, metrics = rliable
    scores = np.random.default_rng(3).gamma(2.0, 1.0, size=shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points, intervals = library.get_interval_estimates(
            {"x": scores}, lambda s: np.array([metrics.aggregate_iqm(s)]), reps=REPS,
            random_state=np.random.RandomState(0),
        )  # fmt: skip
    iqm, low, high = iqm_with_stratified_ci([scores[:, task] for task in range(shape[1])], n_boot=REPS)
    assert iqm == pytest.approx(float(points["x"][0]), rel=1e-12)
    width = float(intervals["x"][1, 0] - intervals["x"][0, 0])
    assert low == pytest.approx(float(intervals["x"][0, 0]), abs=0.1 * width)
    assert high == pytest.approx(float(intervals["x"][1, 0]), abs=0.1 * width)


def test_performance_profile_matches_rliable(rliable):
    library, _ = rliable
    scores = np.random.default_rng(4).normal(1.0, 0.6, size=(20, 4))
    taus = np.linspace(-0.5, 2.0, 26)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        profiles, bands = library.create_performance_profile({"x": scores}, taus, reps=REPS)
    curve, low, high = performance_profile([scores[:, task] for task in range(4)], taus, n_boot=REPS)
    np.testing.assert_allclose(curve, profiles["x"], atol=1e-12)
    np.testing.assert_allclose(low, bands["x"][0], atol=0.05)
    np.testing.assert_allclose(high, bands["x"][1], atol=0.05)


def test_a_success_rate_aggregates_as_its_mean_with_a_stratified_interval():
    """A proportion's aggregate is its mean: 38 successes in 50 episodes are 0.76 (their IQM would be 1), and the
    interval is the mean's percentile bootstrap, resampled within each run."""
    runs = [np.r_[np.ones(13), np.zeros(4)], np.r_[np.ones(12), np.zeros(5)], np.r_[np.ones(13), np.zeros(3)]]
    assert interquartile_mean(np.concatenate(runs)) == 1.0
    mean, low, high = mean_with_stratified_ci(runs)
    assert mean == pytest.approx(38 / 50)
    assert 0.6 < low < mean < high < 0.9
    # By hand: the same resamples' means.
    rng = np.random.default_rng(0)
    means = np.concatenate([np.sort(r)[rng.integers(0, r.size, (2000, r.size))] for r in runs], axis=1).mean(axis=1)
    assert (low, high) == pytest.approx((np.quantile(means, 0.025), np.quantile(means, 0.975)))
