"""The interquartile mean and its (stratified) bootstrap confidence intervals, and performance profiles, as rliable
(Agarwal et al. 2021, "Deep RL at the edge of the statistical precipice") computes them."""

from __future__ import annotations

import numpy as np

__all__ = [
    "interquartile_mean",
    "iqm_with_ci",
    "iqm_with_stratified_ci",
    "mean_with_stratified_ci",
    "performance_profile",
]


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


def iqm_with_stratified_ci(
    groups, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """IQM of all values pooled over ``groups`` (runs) and its stratified bootstrap interval (percentile method).

    Each bootstrap sample resamples every group's values with replacement within that group (its own count), as
    rliable's ``StratifiedBootstrap`` does with runs x tasks, so every run keeps its weight and the interval
    reflects the spread within runs, not the choice of which runs to keep. With one group this is the plain
    bootstrap of :func:`iqm_with_ci`. Returns ``(iqm, low, high)``.
    """
    boots = _stratified_resamples(groups, n_boot, seed)
    boots.sort(axis=1)
    dist = _iqm_of_sorted(boots)
    tail = (1.0 - confidence) / 2
    point = interquartile_mean(np.concatenate([np.asarray(g, dtype=np.float64).ravel() for g in groups]))
    return point, float(np.quantile(dist, tail)), float(np.quantile(dist, 1.0 - tail))


def mean_with_stratified_ci(
    groups, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[float, float, float]:
    """As :func:`iqm_with_stratified_ci`, for the mean: the aggregate of a proportion (a success rate), whose IQM
    would be 1 as soon as three quarters of the episodes succeed. Returns ``(mean, low, high)``."""
    dist = _stratified_resamples(groups, n_boot, seed).mean(axis=1)
    tail = (1.0 - confidence) / 2
    point = float(np.concatenate([np.asarray(g, dtype=np.float64).ravel() for g in groups]).mean())
    return point, float(np.quantile(dist, tail)), float(np.quantile(dist, 1.0 - tail))


def _stratified_resamples(groups, n_boot: int, seed: int) -> np.ndarray:
    """``(n_boot, total)``: each row every group's values resampled with replacement within the group."""
    # Sorted first, so that a draw picks the same value whatever order the episodes came in.
    runs = [np.sort(np.asarray(g, dtype=np.float64).ravel()) for g in groups]
    if not runs or any(r.size == 0 for r in runs):
        raise ValueError("every group needs at least one value")
    rng = np.random.default_rng(seed)
    return np.concatenate([r[rng.integers(0, r.size, size=(n_boot, r.size))] for r in runs], axis=1)


def performance_profile(
    groups, taus, n_boot: int = 2000, seed: int = 0, confidence: float = 0.95
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The score distribution of rliable's performance profiles: for each threshold ``tau``, the fraction of all
    values (pooled over ``groups``: environments x runs) above it, with its stratified bootstrap band (each group
    resampled within itself, as :func:`iqm_with_stratified_ci`). Returns ``(fraction, low, high)``, one per tau."""
    taus = np.asarray(taus, dtype=np.float64)
    boots = _stratified_resamples(groups, n_boot, seed)
    values = np.concatenate([np.asarray(g, dtype=np.float64).ravel() for g in groups])
    curve = (values[None, :] > taus[:, None]).mean(axis=1)
    dist = (boots[:, None, :] > taus[None, :, None]).mean(axis=2)  # (n_boot, taus)
    tail = (1.0 - confidence) / 2
    return curve, np.quantile(dist, tail, axis=0), np.quantile(dist, 1.0 - tail, axis=0)


def iqm_with_ci(values, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean and its 95% bootstrap confidence interval (one run: no strata)."""
    return iqm_with_stratified_ci([values], n_boot=n_boot, seed=seed)
