"""The interquartile mean and its bootstrap confidence intervals, performance profiles, and the comparison of two
policies with the run as the unit, as rliable (Agarwal et al. 2021, "Deep RL at the edge of the statistical
precipice") computes them.

A policy's result on one environment is a list of groups of values: one group per training seed (a run) for a
trained agent, a single group for a deterministic policy (a hand baseline, random), which has no training seed. The
functions that compare policies (:func:`aggregate_with_two_level_ci`, :func:`difference_with_ci`, :func:`compare`,
:func:`probability_of_improvement`) resample the runs, so that an agent whose seeds disagree gets a wide interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from polyenvs.registry import Score

__all__ = [
    "Comparison",
    "Difference",
    "aggregate_with_two_level_ci",
    "compare",
    "difference_with_ci",
    "interquartile_mean",
    "iqm_with_ci",
    "iqm_with_stratified_ci",
    "mean_with_stratified_ci",
    "performance_profile",
    "probability_of_improvement",
    "verdict",
]

#: How a policy's values aggregate: rliable's interquartile mean, or the mean (for a proportion: a success rate).
AGGREGATES = ("iqm", "mean")
#: Which way a score is better: larger ("max") or smaller ("min").
DIRECTIONS = ("max", "min")


def _iqm_of_sorted(sorted_x: np.ndarray) -> np.ndarray:
    """IQM along the last axis of sorted data: the mean of the middle half, ``floor(n/4)`` cut from each end (the
    same as ``scipy.stats.trim_mean(x, 0.25)``, which rliable uses)."""
    n = sorted_x.shape[-1]
    lo, hi = int(np.floor(0.25 * n)), int(np.ceil(0.75 * n))
    return sorted_x[..., lo:hi].mean(axis=-1)


def interquartile_mean(values) -> float:
    """The interquartile mean of ``values`` (the mean of the middle 50%)."""
    x = np.sort(np.asarray(values, dtype=np.float64).ravel())
    if x.size == 0:
        raise ValueError("the IQM of no values is undefined")
    return float(_iqm_of_sorted(x))


def _aggregate_rows(values: np.ndarray, aggregate: str) -> np.ndarray:
    """``aggregate`` ("iqm" or "mean") along the last axis of ``values``."""
    if aggregate == "iqm":
        return _iqm_of_sorted(np.sort(values, axis=-1))
    return values.mean(axis=-1)


def _pooled(groups, aggregate: str) -> float:
    """The point estimate: ``aggregate`` of all values of ``groups`` pooled, in the order given."""
    return float(_aggregate_rows(np.concatenate([np.asarray(g, dtype=np.float64).ravel() for g in groups]), aggregate))


def _check_choice(name: str, value, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r}")


def _check_bootstrap(n_boot, confidence) -> None:
    if isinstance(n_boot, bool) or not isinstance(n_boot, int | np.integer) or n_boot < 1:
        raise ValueError(f"n_boot must be a positive integer, got {n_boot!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie strictly between 0 and 1, got {confidence!r}")


def _runs(groups, name: str = "groups") -> list[np.ndarray]:
    """Each group's values as a sorted float array; ValueError naming ``name`` unless every group has finite values."""
    # Sorted, so that a draw picks the same value whatever order the episodes came in.
    runs = [np.sort(np.asarray(g, dtype=np.float64).ravel()) for g in groups]
    if not runs or any(r.size == 0 for r in runs):
        raise ValueError(f"{name}: every group needs at least one value, got sizes {[r.size for r in runs]}")
    if not all(np.isfinite(r).all() for r in runs):
        raise ValueError(f"{name}: every value must be finite")
    return runs


def _percentiles(dist: np.ndarray, confidence: float) -> tuple[float, float]:
    """The percentile interval of the bootstrap distribution ``dist`` at ``confidence``."""
    tail = (1.0 - confidence) / 2
    return float(np.quantile(dist, tail)), float(np.quantile(dist, 1.0 - tail))


# ------------------------------------------------------------------------- within runs (today's leaderboard)


def iqm_with_stratified_ci(
    groups, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """IQM of all values pooled over ``groups`` (runs) and its stratified bootstrap interval (percentile method).

    Each bootstrap sample resamples every group's values with replacement within that group (its own count), as
    rliable's ``StratifiedBootstrap`` does with runs x tasks, so every run keeps its weight and the interval
    reflects the spread within runs, not the choice of which runs to keep (for that, see
    :func:`aggregate_with_two_level_ci`). With one group this is the plain bootstrap of :func:`iqm_with_ci`.
    Returns ``(iqm, low, high)``.
    """
    dist = _aggregate_rows(_stratified_resamples(groups, n_boot, seed, confidence), "iqm")
    return _pooled(groups, "iqm"), *_percentiles(dist, confidence)


def mean_with_stratified_ci(
    groups, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """As :func:`iqm_with_stratified_ci`, for the mean: the aggregate of a proportion (a success rate), whose IQM
    would be 1 as soon as three quarters of the episodes succeed. Returns ``(mean, low, high)``."""
    dist = _aggregate_rows(_stratified_resamples(groups, n_boot, seed, confidence), "mean")
    return _pooled(groups, "mean"), *_percentiles(dist, confidence)


def _stratified_resamples(groups, n_boot: int, seed: int, confidence: float) -> np.ndarray:
    """``(n_boot, total)``: each row every group's values resampled with replacement within the group."""
    runs = _runs(groups)
    _check_bootstrap(n_boot, confidence)
    rng = np.random.default_rng(seed)
    return np.concatenate([r[rng.integers(0, r.size, size=(n_boot, r.size))] for r in runs], axis=1)


def performance_profile(
    groups, taus, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The score distribution of rliable's performance profiles: for each threshold ``tau``, the fraction of all
    values (pooled over ``groups``: environments x runs) above it, with its stratified bootstrap band (each group
    resampled within itself, as :func:`iqm_with_stratified_ci`). Returns ``(fraction, low, high)``, one per tau."""
    taus = np.asarray(taus, dtype=np.float64)
    boots = _stratified_resamples(groups, n_boot, seed, confidence)
    values = np.concatenate([np.asarray(g, dtype=np.float64).ravel() for g in groups])
    curve = (values[None, :] > taus[:, None]).mean(axis=1)
    dist = (boots[:, None, :] > taus[None, :, None]).mean(axis=2)  # (n_boot, taus)
    tail = (1.0 - confidence) / 2
    return curve, np.quantile(dist, tail, axis=0), np.quantile(dist, 1.0 - tail, axis=0)


def iqm_with_ci(values, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean and its 95% bootstrap confidence interval (one run: no strata)."""
    return iqm_with_stratified_ci([values], n_boot=n_boot, seed=seed)


# ----------------------------------------------------------------------------------- the run as the unit


def _two_level_resamples(runs: list[np.ndarray], n_boot: int, rng: np.random.Generator) -> np.ndarray:
    """``(n_boot, total)``: each row fills every run's slot with a run drawn with replacement, then with as many of
    the drawn run's values as the slot holds, drawn with replacement (all runs hold the protocol's episode count in
    practice, and then every slot is one whole resampled run)."""
    sizes = np.array([r.size for r in runs])
    values, starts = np.concatenate(runs), np.cumsum(sizes) - sizes
    # A single group (a deterministic policy) has no runs to draw: its resample is the plain episode bootstrap,
    # draw for draw the one of iqm_with_stratified_ci, so its interval is the same as there.
    drawn = rng.integers(0, len(runs), size=(n_boot, len(runs))) if len(runs) > 1 else np.zeros((n_boot, 1), int)
    run_of_value = np.repeat(drawn, sizes, axis=1)  # each slot's run, once per value the slot holds
    return values[starts[run_of_value] + rng.integers(0, sizes[run_of_value])]


def aggregate_with_two_level_ci(
    groups, aggregate: str = "iqm", n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """``aggregate`` ("iqm" or "mean") of all values pooled over ``groups`` and its two-level bootstrap interval.

    Each bootstrap sample draws the runs (training seeds) with replacement, then the episodes within each drawn run
    with replacement, so the interval shows the seed-to-seed spread that rliable reports with the run as the unit
    (:func:`iqm_with_stratified_ci` keeps every run and shows the spread within runs only). With a single group it
    is the plain episode bootstrap, the same numbers as :func:`iqm_with_stratified_ci` and
    :func:`mean_with_stratified_ci`. Returns ``(value, low, high)``.
    """
    runs = _runs(groups)
    _check_choice("aggregate", aggregate, AGGREGATES)
    _check_bootstrap(n_boot, confidence)
    dist = _aggregate_rows(_two_level_resamples(runs, n_boot, np.random.default_rng(seed)), aggregate)
    return _pooled(groups, aggregate), *_percentiles(dist, confidence)


@dataclass(frozen=True)
class Difference:
    """An agent's aggregate of a score minus a reference policy's (the paper's algorithm, a row's anchor), with the
    percentile interval of that difference: the effect size of the verdict."""

    agent: float  #: the agent's aggregate, all its values pooled
    reference: float  #: the reference's aggregate, all its values pooled
    low: float
    high: float

    @property
    def value(self) -> float:
        """Agent minus reference."""
        return self.agent - self.reference

    @property
    def relative(self) -> float | None:
        """The difference over the reference's magnitude (0.1: ten per cent of the reference's value); None where
        the reference is 0 and there is no scale to relate to."""
        return self.value / abs(self.reference) if self.reference != 0 else None


def difference_with_ci(
    agent_groups,
    reference_groups,
    aggregate: str = "iqm",
    n_boot: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> Difference:
    """The difference agent minus reference of ``aggregate`` ("iqm" or "mean") and its bootstrap interval.

    Each side is resampled on its own by :func:`aggregate_with_two_level_ci`'s scheme (runs, then episodes within
    them; a single group by its episodes), independently of the other, as rliable's
    ``StratifiedIndependentBootstrap`` does for metrics of two algorithms: the policies' runs are unrelated.
    """
    agent, reference = _runs(agent_groups, "agent_groups"), _runs(reference_groups, "reference_groups")
    _check_choice("aggregate", aggregate, AGGREGATES)
    _check_bootstrap(n_boot, confidence)
    rng = np.random.default_rng(seed)
    agent_dist = _aggregate_rows(_two_level_resamples(agent, n_boot, rng), aggregate)
    dist = agent_dist - _aggregate_rows(_two_level_resamples(reference, n_boot, rng), aggregate)
    low, high = _percentiles(dist, confidence)
    return Difference(_pooled(agent_groups, aggregate), _pooled(reference_groups, aggregate), low, high)


def verdict(difference: Difference, direction: str) -> str:
    """``"better"`` where the interval of agent minus reference lies wholly on the better side of 0 (above for
    ``direction`` "max", below for "min"), ``"worse"`` where it lies wholly on the other side, else ``"tied"``."""
    _check_choice("direction", direction, DIRECTIONS)
    sign = 1.0 if direction == "max" else -1.0
    worst, best = sorted((sign * difference.low, sign * difference.high))
    return "better" if worst > 0 else "worse" if best < 0 else "tied"


@dataclass(frozen=True)
class Comparison:
    """The verdict on an agent against a reference: ``outcome`` ("better", "worse", "tied"), the task score's
    :class:`Difference`, and the tie-break metric's where it decided (both at the score's ceiling)."""

    outcome: str
    score: Difference
    tie_break: Difference | None = None


def compare(
    agent_groups,
    reference_groups,
    task_score: Score,
    *,
    agent_tie_groups=None,
    reference_tie_groups=None,
    n_boot: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> Comparison:
    """Whether an agent beats a reference on a task score (per training seed, or one group: its values).

    ``task_score`` says how (a registry row's :class:`~polyenvs.registry.Score`, or anything with its ``aggregate``,
    ``direction``, ``ceiling`` and ``tie_direction``). The outcome is :func:`verdict` on :func:`difference_with_ci`
    of the score. Where that is a tie with both policies' aggregates at the score's ``ceiling`` (a success rate of 1,
    say), the tie-break metric decides: the same interval of the difference of its mean (``agent_tie_groups`` minus
    ``reference_tie_groups``), better in ``tie_direction`` (faster to the goal, for instance). Without tie-break
    values a tie stays a tie.
    """
    _check_choice("tie_direction", task_score.tie_direction, DIRECTIONS)
    _check_choice("direction", task_score.direction, DIRECTIONS)
    score = difference_with_ci(agent_groups, reference_groups, task_score.aggregate, n_boot, seed, confidence)
    outcome = verdict(score, task_score.direction)
    ceiling = task_score.ceiling
    at_ceiling = ceiling is not None and score.agent == score.reference == ceiling
    if outcome != "tied" or not at_ceiling or agent_tie_groups is None or reference_tie_groups is None:
        return Comparison(outcome, score)
    tie = difference_with_ci(agent_tie_groups, reference_tie_groups, "mean", n_boot, seed, confidence)
    return Comparison(verdict(tie, task_score.tie_direction), score, tie)


def _improvement(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per row of ``x`` ``(rows, runs_x)`` and ``y`` ``(rows, runs_y)``: the fraction of pairs with x above y, ties
    counting half (the Mann-Whitney U statistic over ``runs_x * runs_y``)."""
    return ((np.sign(x[:, :, None] - y[:, None, :]) + 1.0) / 2.0).mean(axis=(1, 2))


def probability_of_improvement(
    x_groups,
    y_groups,
    aggregate: str = "iqm",
    direction: str = "max",
    *,
    n_boot: int = 2000,
    seed: int = 0,
    confidence: float = 0.95,
) -> tuple[float, float, float]:
    """rliable's probability of improvement P(X > Y) of policy X (an agent) over Y (the paper's algorithm) on one
    task, with rliable's stratified bootstrap interval. Returns ``(probability, low, high)``.

    rliable takes one score per run (``scores_x`` of shape ``(num_runs, num_tasks)``), P(X > Y) the chance that a
    run of X scores above a run of Y (the Mann-Whitney U statistic over all pairs, ties counting half), and
    resamples each algorithm's runs independently. Here a run's score is its group's ``aggregate`` ("iqm" or
    "mean") over its episodes, "above" is better in ``direction`` (below for "min"), and a single group (a hand
    baseline, which has no training seed) is one run: a deterministic policy run again gives the same result, and
    its episodes are not runs, as comparing a run's aggregate with single episodes would compare unlike quantities
    (a success rate of 0.9 against episodes that each score 0 or 1). Against one run, P is the fraction of X's
    runs that beat it, and the interval shows X's seed-to-seed spread only.
    """
    _check_choice("direction", direction, DIRECTIONS)
    x, y = _run_scores(x_groups, aggregate, "x_groups"), _run_scores(y_groups, aggregate, "y_groups")
    _check_bootstrap(n_boot, confidence)
    sign = 1.0 if direction == "max" else -1.0
    x, y = sign * x, sign * y
    rng = np.random.default_rng(seed)
    boot_x = x[rng.integers(0, x.size, size=(n_boot, x.size))]
    boot_y = y[rng.integers(0, y.size, size=(n_boot, y.size))]
    return float(_improvement(x[None], y[None])[0]), *_percentiles(_improvement(boot_x, boot_y), confidence)


def _run_scores(groups, aggregate: str, name: str) -> np.ndarray:
    """Each group's ``aggregate`` over its values: one score per run."""
    runs = _runs(groups, name)
    _check_choice("aggregate", aggregate, AGGREGATES)
    return np.array([_aggregate_rows(r, aggregate) for r in runs])
