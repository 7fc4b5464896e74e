"""Statistics across seeds, as Agarwal et al. (2021, "Deep RL at the edge of the statistical
precipice") recommend them, computed with scipy (rliable does not import beside pandas 3):

- IQM: the interquartile mean, the mean of the middle 50% of runs (``trim_mean(x, 0.25)``):
  robust to one outlying seed, less noisy than the median;
- stratified bootstrap confidence intervals: runs are resampled with replacement within
  each stratum (each env: tasks are not exchangeable), the statistic recomputed on every
  resample, and the percentile interval taken;
- probability of improvement P(X > Y): the chance that a run of X beats a run of Y, ties
  counting half: the Mann-Whitney U statistic over the number of pairs (one env at a
  time); for frames with labelled frames charged, where a run that never got there is
  only a lower bound, pairs whose order that hides count half (Gehan's generalised
  Wilcoxon).

Every bootstrap has a fixed seed, so a report prints the same intervals each time. A NaN
value (a diverged seed's return) is left out of every statistic here, as ``mean`` in pandas
leaves it out; the report's seed counts still show it.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np
from scipy import stats

CONFIDENCE = 0.95
RESAMPLES = 2000
SEED = 0


def _finite(values: Sequence[float]) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[~np.isnan(values)]


def iqm(values: Sequence[float], axis: int = -1) -> float | np.ndarray:
    """The mean of the middle 50% (a quarter trimmed from each end; scipy trims
    ``int(0.25 n)`` values from each end, as rliable does). On a 1-D input NaNs are left
    out (NaN when nothing is left); ``axis`` serves the vectorised bootstrap."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = _finite(values)
        if not len(values):
            return float("nan")
    return stats.trim_mean(values, 0.25, axis=axis)


def _percentile_ci(samples: Sequence[np.ndarray], statistic: Callable[..., np.ndarray],
                   confidence: float, resamples: int, seed: int) -> tuple[float, float]:
    samples = [_finite(s) for s in samples]
    if any(len(s) < 2 for s in samples):
        return float("nan"), float("nan")  # one run has no spread to resample
    if all(np.ptp(s) == 0 for s in samples):
        value = float(statistic(*samples, axis=-1))
        return value, value  # every resample gives the same value
    result = stats.bootstrap(samples, statistic, n_resamples=resamples,
                             confidence_level=confidence, method="percentile",
                             paired=False, vectorized=True, axis=-1,
                             rng=np.random.default_rng(seed))
    low, high = result.confidence_interval
    return float(low), float(high)


def stratified_ci(strata: Sequence[Sequence[float]], statistic: Callable[..., np.ndarray] = iqm,
                  confidence: float = CONFIDENCE, resamples: int = RESAMPLES,
                  seed: int = SEED) -> tuple[float, float]:
    """Percentile bootstrap interval of ``statistic`` over the runs of all strata pooled,
    each stratum resampled on its own. ``statistic(values, axis)`` must reduce ``axis``.
    (NaN, NaN) when a stratum has fewer than two runs."""

    def pooled(*resampled, axis=-1):
        return statistic(np.concatenate(resampled, axis=axis), axis=axis)

    return _percentile_ci(strata, pooled, confidence, resamples, seed)


def probability_of_improvement(x: Sequence[float], y: Sequence[float]) -> float:
    """P(X > Y) + P(X = Y) / 2 over all pairs of a run of X and a run of Y."""
    x, y = _finite(x), _finite(y)
    if not len(x) or not len(y):
        return float("nan")
    return float(stats.mannwhitneyu(x, y).statistic / (len(x) * len(y)))


def _pairwise_improvement(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    x, y = np.moveaxis(x, axis, -1), np.moveaxis(y, axis, -1)
    greater = (x[..., :, None] > y[..., None, :]).mean(axis=(-2, -1))
    ties = (x[..., :, None] == y[..., None, :]).mean(axis=(-2, -1))
    return greater + 0.5 * ties


def improvement_ci(x: Sequence[float], y: Sequence[float], confidence: float = CONFIDENCE,
                   resamples: int = RESAMPLES, seed: int = SEED) -> tuple[float, float]:
    """Percentile bootstrap interval of P(X > Y), the runs of X and of Y resampled
    independently."""
    return _percentile_ci([x, y], _pairwise_improvement, confidence, resamples, seed)


def _censored_improvement(x: np.ndarray, x_censored: np.ndarray, y: np.ndarray,
                          y_censored: np.ndarray) -> np.ndarray:
    """Over the last axis: the share of pairs in which X needed fewer frames than Y. A
    censored value is the least a run would have needed (it never got there within its
    budget), so a pair whose order it hides counts half: X wins where its value is known
    and below Y's (known or least), and loses the same way."""
    xv, yv = x[..., :, None], y[..., None, :]
    x_wins = (xv < yv) & ~x_censored[..., :, None]
    y_wins = (yv < xv) & ~y_censored[..., None, :]
    return (x_wins + 0.5 * ~(x_wins | y_wins)).mean(axis=(-2, -1))


def censored_improvement(x: Sequence[float], x_censored: Sequence[bool],
                         y: Sequence[float], y_censored: Sequence[bool]) -> float:
    """P(X needs fewer frames than Y) + half the pairs whose order is unknown, where a
    censored value is a lower bound: a run that never reached the threshold needs at least
    its budget (plus any labelled frames charged to it). Two such runs, or a run that got
    there later than the other's lower bound, are not ordered by the data: they count half,
    as Gehan's generalised Wilcoxon test counts them. Without censoring, P(X < Y) with
    ties half."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if not len(x) or not len(y):
        return float("nan")
    return float(_censored_improvement(x, np.asarray(x_censored, dtype=bool), y,
                                       np.asarray(y_censored, dtype=bool)))


def censored_improvement_ci(x: Sequence[float], x_censored: Sequence[bool],
                            y: Sequence[float], y_censored: Sequence[bool],
                            confidence: float = CONFIDENCE, resamples: int = RESAMPLES,
                            seed: int = SEED) -> tuple[float, float]:
    """Percentile bootstrap interval of :func:`censored_improvement`, the runs of X and of Y
    (each with its censoring) resampled independently."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    xc, yc = np.asarray(x_censored, dtype=bool), np.asarray(y_censored, dtype=bool)
    if len(x) < 2 or len(y) < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    ix = rng.integers(0, len(x), (resamples, len(x)))
    iy = rng.integers(0, len(y), (resamples, len(y)))
    values = _censored_improvement(x[ix], xc[ix], y[iy], yc[iy])
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return float(low), float(high)


def mean_ci(curves: np.ndarray, confidence: float = CONFIDENCE, resamples: int = RESAMPLES,
            seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    """Per column of ``curves`` (seeds × points), the percentile bootstrap interval of the
    mean over seeds: the band of a learning-curve plot. NaN with fewer than two seeds."""
    curves = np.asarray(curves, dtype=float)
    if curves.shape[0] < 2:
        nan = np.full(curves.shape[1], np.nan)
        return nan, nan.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # columns where every seed is equal: a zero band
        result = stats.bootstrap((curves,), np.mean, n_resamples=resamples,
                                 confidence_level=confidence, method="percentile",
                                 vectorized=True, axis=0, rng=np.random.default_rng(seed))
    low, high = (np.asarray(v, dtype=float) for v in result.confidence_interval)
    flat = np.ptp(curves, axis=0) == 0
    low[flat] = high[flat] = curves[0, flat]
    return low, high
