"""The interquartile mean and its (stratified) bootstrap confidence intervals, as rliable computes them."""

from __future__ import annotations

import numpy as np

__all__ = ["interquartile_mean", "iqm_with_ci", "iqm_with_stratified_ci"]


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
    runs = [np.sort(np.asarray(g, dtype=np.float64).ravel()) for g in groups]  # sorted: reproduces iqm_with_ci
    if not runs or any(r.size == 0 for r in runs):
        raise ValueError("every group needs at least one value")
    rng = np.random.default_rng(seed)
    boots = np.concatenate([r[rng.integers(0, r.size, size=(n_boot, r.size))] for r in runs], axis=1)
    boots.sort(axis=1)
    dist = _iqm_of_sorted(boots)
    tail = (1.0 - confidence) / 2
    point = interquartile_mean(np.concatenate(runs))
    return point, float(np.quantile(dist, tail)), float(np.quantile(dist, 1.0 - tail))


def iqm_with_ci(values, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Interquartile mean and its 95% bootstrap confidence interval (one run: no strata)."""
    return iqm_with_stratified_ci([values], n_boot=n_boot, seed=seed)
