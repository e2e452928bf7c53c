"""Our statistics against rliable's on the same data: the IQM, its stratified bootstrap interval and performance
profile, and the comparisons with the run as the unit (the two-level interval, the difference of two policies, the
probability of improvement).

rliable (Agarwal et al. 2021) takes a ``(runs, tasks)`` score matrix and resamples runs within each task
(``StratifiedBootstrap``); ours takes groups and resamples values within each group, so its groups are the matrix's
columns. The point estimates must agree exactly; the percentile intervals within bootstrap noise (the same number of
resamples, 2000, but other random draws): a tenth of the interval's width. rliable has no two-level bootstrap (runs,
then episodes within them): with one value per run ours is its bootstrap of runs, and with more its spread is
checked against the two-stage variance formula.
"""

from __future__ import annotations

import dataclasses
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from polyenvs.evaluation.statistics import (
    Difference,
    aggregate_with_two_level_ci,
    compare,
    difference_with_ci,
    interquartile_mean,
    iqm_with_stratified_ci,
    mean_with_stratified_ci,
    performance_profile,
    probability_of_improvement,
    verdict,
)
from polyenvs.registry import Score

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


@pytest.fixture
def rliable_draws():
    """rliable's bootstraps draw from numpy's global generator (``np.random.choice`` in ``update_indices``) whatever
    ``random_state`` says: seed it, so that these comparisons are reproducible, and put its state back after."""
    # The legacy global generator on purpose: it is the one rliable draws from.
    state = np.random.get_state()  # noqa: NPY002
    np.random.seed(0)  # noqa: NPY002
    yield
    np.random.set_state(state)  # noqa: NPY002


def _rliable_interval(rliable, scores, func) -> tuple[float, float, float]:
    """rliable's point and percentile interval (REPS resamples) of ``func`` on ``scores`` (an array, or a list of
    arrays resampled independently)."""
    library, _ = rliable
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points, intervals = library.get_interval_estimates({"x": scores}, lambda *s: np.array([func(*s)]), reps=REPS)
    return float(points["x"][0]), float(intervals["x"][0, 0]), float(intervals["x"][1, 0])


def _assert_like_rliable(ours, theirs):
    """Points equal; interval ends within a tenth of the width: with 2000 resamples an end's bootstrap noise is
    about 1.5% of the width (the 2.5% quantile's standard error, 0.06 sd, over a width of 3.9 sd), so a tenth is
    four and a half standard errors of the two ends' difference, while a wrong scheme misses by far more."""
    width = theirs[2] - theirs[1]
    assert ours[0] == pytest.approx(theirs[0], rel=1e-12, abs=1e-12)
    assert ours[1] == pytest.approx(theirs[1], abs=0.1 * width)
    assert ours[2] == pytest.approx(theirs[2], abs=0.1 * width)


@pytest.mark.parametrize("shape", [(50, 3), (10, 5), (51, 1)], ids=lambda s: f"{s[0]}runs x {s[1]}tasks")
def test_iqm_and_its_stratified_interval_match_rliable(rliable, rliable_draws, shape):
    _, metrics = rliable
    scores = np.random.default_rng(3).gamma(2.0, 1.0, size=shape)
    ours = iqm_with_stratified_ci([scores[:, task] for task in range(shape[1])], n_boot=REPS)
    _assert_like_rliable(ours, _rliable_interval(rliable, scores, metrics.aggregate_iqm))


def test_performance_profile_matches_rliable(rliable, rliable_draws):
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


# ------------------------------------------------------------------------------------------ the run as the unit


def _successes(k: int, n: int = 50) -> np.ndarray:
    """A run's success flags: ``k`` of ``n`` episodes succeed."""
    return np.r_[np.ones(k), np.zeros(n - k)]


@pytest.mark.parametrize("aggregate", ["iqm", "mean"])
def test_a_single_group_is_the_plain_episode_bootstrap_of_today(aggregate):
    """A hand baseline (one group, no training seed) keeps its interval: the same numbers as the stratified one."""
    values = np.random.default_rng(5).gamma(2.0, 1.0, size=50)
    stratified = iqm_with_stratified_ci if aggregate == "iqm" else mean_with_stratified_ci
    assert aggregate_with_two_level_ci([values], aggregate, seed=7) == stratified([values], seed=7)


@pytest.mark.parametrize("aggregate", ["iqm", "mean"])
def test_the_two_level_interval_resamples_runs_as_rliable_does(rliable, rliable_draws, aggregate):
    """Runs of one value each: the two-level bootstrap is rliable's bootstrap of the runs, ``(runs, 1 task)``."""
    _, metrics = rliable
    scores = np.random.default_rng(6).gamma(2.0, 1.0, size=(12, 1))
    func = metrics.aggregate_iqm if aggregate == "iqm" else metrics.aggregate_mean
    ours = aggregate_with_two_level_ci(list(scores), aggregate, n_boot=REPS)
    _assert_like_rliable(ours, _rliable_interval(rliable, scores, func))


def test_the_two_level_spread_of_the_mean_is_the_two_stage_value():
    """Drawing R runs, then k episodes within each, the pooled mean varies by (B + W/k) / R: B the variance of the
    runs' means, W their variance within (both of the data, as the bootstrap sees them). Here W/k = B, so
    resampling the episodes only (W/(kR)) or the runs only (B/R) would give a spread sqrt(2) too small."""
    k, means = 25, np.linspace(0.0, 0.7, 8)
    z = np.random.default_rng(8).standard_normal(k)
    z = (z - z.mean()) / z.std()  # mean 0, variance 1
    between = means.var()
    runs = [mu + np.sqrt(k * between) * z for mu in means]  # W = k * B
    _, low, high = aggregate_with_two_level_ci(runs, "mean", n_boot=20000)
    # Near normal: 95% of it within 1.96 sd; 20000 resamples pin the width to about 1%.
    assert (high - low) / (2 * 1.96) == pytest.approx(np.sqrt(2 * between / len(means)), rel=0.05)


@pytest.mark.parametrize("aggregate", ["iqm", "mean"])
def test_the_difference_interval_matches_rliable(rliable, rliable_draws, aggregate):
    """An agent's runs (one value each) minus a hand baseline's episodes, each resampled on its own: rliable's
    ``StratifiedIndependentBootstrap`` of the two score arrays, with the difference of the aggregates as metric."""
    _, metrics = rliable
    rng = np.random.default_rng(9)
    agent, reference = rng.gamma(4.0, 1.0, size=(10, 1)), rng.gamma(2.0, 1.0, size=(50, 1))
    func = metrics.aggregate_iqm if aggregate == "iqm" else metrics.aggregate_mean
    diff = difference_with_ci(list(agent), [reference.ravel()], aggregate, n_boot=REPS)
    theirs = _rliable_interval(rliable, [agent, reference], lambda x, y: func(x) - func(y))
    _assert_like_rliable((diff.value, diff.low, diff.high), theirs)
    assert (diff.agent, diff.reference) == (pytest.approx(func(agent)), pytest.approx(func(reference)))


def test_probability_of_improvement_matches_rliable(rliable, rliable_draws):
    """Runs of 20 episodes of success flags: each run's success rate is a run score, many of them equal (ties count
    half); P(X > Y) and its interval as rliable's ``probability_of_improvement`` on those scores."""
    _, metrics = rliable
    rng = np.random.default_rng(10)
    x_runs, y_runs = rng.random((10, 20)) < 0.7, rng.random((8, 20)) < 0.6
    x, y = x_runs.mean(axis=1, keepdims=True), y_runs.mean(axis=1, keepdims=True)
    assert len(np.unique(np.r_[x, y])) < x.size + y.size  # there are ties
    ours = probability_of_improvement(list(x_runs), list(y_runs), "mean", n_boot=REPS)
    _assert_like_rliable(ours, _rliable_interval(rliable, [x, y], metrics.probability_of_improvement))


def test_probability_of_improvement_over_a_hand_baseline_counts_the_seeds_that_beat_it():
    """The issue's corridor PPO (seeds 1.0, 0.96, 0.53) against a hand baseline at 0.9 (its one run): two of the
    three seeds beat it; for an error (smaller is better) the same runs improve on it where they score below."""
    seeds = [_successes(50), _successes(48), _successes(26, 49)]
    baseline = [_successes(45)]
    p, low, high = probability_of_improvement(seeds, baseline, "mean")
    assert (p, low, high) == (pytest.approx(2 / 3), 0.0, 1.0)
    assert probability_of_improvement(seeds, baseline, "mean", direction="min")[0] == pytest.approx(1 / 3)


def test_a_failing_seed_widens_the_interval_and_turns_better_into_tied():
    """Three seeds succeed in 50, 49 and 48 of 50 episodes, beating a hand baseline at 35 of 50. A fourth seed that
    fails every episode adds no spread within runs, so the episode-only interval narrows; the two-level one
    widens fourteen-fold, and the agent no longer beats the baseline."""
    three = [_successes(50), _successes(49), _successes(48)]
    four = [*three, _successes(0)]
    baseline = [_successes(35)]
    assert verdict(difference_with_ci(three, baseline, "mean"), "max") == "better"
    assert verdict(difference_with_ci(four, baseline, "mean"), "max") == "tied"

    def width(interval):
        return interval[2] - interval[1]

    assert width(mean_with_stratified_ci(four)) <= width(mean_with_stratified_ci(three))
    assert width(aggregate_with_two_level_ci(four, "mean")) > 10 * width(aggregate_with_two_level_ci(three, "mean"))


def test_the_verdict_follows_the_direction():
    """An error (smaller is better): an agent whose errors are half the reference's is better for "min" and worse
    for "max"; an interval across 0 is a tie either way."""
    rng = np.random.default_rng(11)
    agent = [rng.normal(1.0, 0.2, size=50) for _ in range(3)]
    reference = [rng.normal(2.0, 0.3, size=50)]
    assert compare(agent, reference, Score("error", direction="min")).outcome == "better"
    assert compare(agent, reference, Score("error", direction="max")).outcome == "worse"
    across = Difference(agent=1.0, reference=1.0, low=-0.1, high=0.2)
    assert verdict(across, "min") == verdict(across, "max") == "tied"


def test_the_effect_size_is_the_difference_and_its_relative_change():
    below = Difference(agent=0.6, reference=-0.8, low=1.0, high=1.8)
    assert (below.value, below.relative) == (pytest.approx(1.4), pytest.approx(1.75))  # over |reference|
    assert Difference(agent=0.5, reference=0.0, low=0.1, high=0.9).relative is None


def test_a_tie_at_the_ceiling_is_decided_by_the_tie_break_interval():
    """Both always reach the goal (a success rate of 1, the ceiling): the agent, 6 s faster with a spread of 1-3 s,
    wins on the time to the goal; a 0.3 s lead in that spread is a tie, and so is a score below the ceiling."""
    rng = np.random.default_rng(12)
    agent, reference = [_successes(50)] * 3, [_successes(50)]
    agent_times = [rng.normal(14.0, 1.0, size=50) for _ in range(3)]
    reference_times = [rng.normal(20.0, 3.0, size=50)]
    ceiling = Score("success", aggregate="mean", ceiling=1.0, tie_direction="min")
    faster = compare(agent, reference, ceiling, agent_tie_groups=agent_times, reference_tie_groups=reference_times)
    assert (faster.outcome, faster.score.value) == ("better", 0.0)
    assert faster.tie_break.high < 0
    close = [rng.normal(19.7, 3.0, size=50)]
    assert (
        compare(agent, reference, ceiling, agent_tie_groups=close, reference_tie_groups=reference_times).outcome
        == "tied"
    )
    below = compare(
        agent, [_successes(49)], ceiling, agent_tie_groups=agent_times, reference_tie_groups=reference_times
    )
    assert (below.outcome, below.tie_break) == ("tied", None)


def test_the_comparisons_are_deterministic_given_the_seed():
    rng = np.random.default_rng(13)
    agent = [rng.normal(1.0, 0.5, size=50) for _ in range(3)]
    reference = [rng.normal(0.8, 0.5, size=50)]
    shuffled = [rng.permutation(run) for run in agent]  # the episodes' order does not matter
    for f in (
        aggregate_with_two_level_ci,
        lambda a: difference_with_ci(a, reference),
        lambda a: probability_of_improvement(a, reference),
    ):
        assert f(agent) == f(agent) == f(shuffled)
    assert difference_with_ci(agent, reference, seed=1) != difference_with_ci(agent, reference, seed=2)


def _unchecked_score(**fields) -> SimpleNamespace:
    """A task score that skips :class:`Score`'s own checks, so that :func:`compare`'s are the ones tested."""
    return SimpleNamespace(**{**dataclasses.asdict(Score("score")), **fields})


@pytest.mark.parametrize(
    ("call", "name"),
    [
        pytest.param(lambda g: aggregate_with_two_level_ci(g, "median"), "aggregate", id="aggregate"),
        pytest.param(lambda g: aggregate_with_two_level_ci(g, n_boot=0), "n_boot", id="n_boot"),
        pytest.param(lambda g: aggregate_with_two_level_ci(g, confidence=1.0), "confidence", id="confidence"),
        pytest.param(lambda g: aggregate_with_two_level_ci([*g, []]), "groups", id="an empty group"),
        pytest.param(lambda g: aggregate_with_two_level_ci([]), "groups", id="no groups"),
        pytest.param(lambda g: difference_with_ci(g, [[np.nan]]), "reference_groups", id="nan"),
        pytest.param(lambda g: verdict(difference_with_ci(g, g), "up"), "direction", id="verdict direction"),
        pytest.param(
            lambda g: compare(g, g, _unchecked_score(tie_direction="fast")), "tie_direction", id="tie_direction"
        ),
        pytest.param(lambda g: probability_of_improvement([[]], g), "x_groups", id="x_groups"),
        pytest.param(lambda g: probability_of_improvement(g, g, direction="up"), "direction", id="P direction"),
    ],
)
def test_bad_input_raises_a_value_error_naming_it_and_changes_nothing(call, name):
    groups = [np.array([3.0, 1.0, 2.0]), np.array([0.5, 4.0])]
    with pytest.raises(ValueError, match=name):
        call(groups)
    np.testing.assert_array_equal(groups[0], [3.0, 1.0, 2.0])
