"""The statistics against values worked by hand."""

import numpy as np
import pytest

from senbench.analysis.stats import (
    censored_improvement,
    censored_improvement_ci,
    improvement_ci,
    iqm,
    mean_ci,
    probability_of_improvement,
    stratified_ci,
)


def test_iqm_is_the_mean_of_the_middle_half():
    # 8 runs: the lowest 2 and the highest 2 are dropped -> mean(3, 4, 5, 6)
    assert iqm([100, 1, 2, 3, 4, 5, 6, 7]) == pytest.approx(4.5)
    # 5 runs: int(5 / 4) = 1 dropped at each end -> mean(2, 3, 4)
    assert iqm([1, 2, 3, 4, -50]) == pytest.approx((1 + 2 + 3) / 3)
    assert iqm([7.0]) == 7.0


def test_probability_of_improvement_counts_pairs_and_half_ties():
    # x=1 beats 0; x=2 beats 0 and ties both 2s; x=3 beats all three: (1 + 2 + 3) / 9
    assert probability_of_improvement([1, 2, 3], [2, 2, 0]) == pytest.approx(6 / 9)
    assert probability_of_improvement([5, 6], [1, 2]) == 1.0
    assert probability_of_improvement([1, 2], [5, 6]) == 0.0
    assert probability_of_improvement([3, 3], [3, 3]) == 0.5


def test_charged_frames_of_a_seed_that_never_got_there_are_only_a_lower_bound():
    # A: 1,000 labelled frames; B: none; budget 10,000. A's seed that got there at 5,000
    # online (6,000 charged) beats B's unreached seeds (at least 10,000); A's unreached
    # seed (at least 11,000) against B's unreached ones: unknown, half; against B's seed at
    # 4,000: B sooner. A's seed at 9,500 online (10,500 charged) against an unreached B:
    # B needs more than 10,000, maybe less than 10,500: unknown, half.
    a, a_never = [6_000, 11_000, 10_500], [False, True, False]
    b, b_never = [10_000, 10_000, 4_000], [True, True, False]
    wins = {(0, 0): 1, (0, 1): 1, (0, 2): 0, (1, 0): 0.5, (1, 1): 0.5, (1, 2): 0,
            (2, 0): 0.5, (2, 1): 0.5, (2, 2): 0}
    assert censored_improvement(a, a_never, b, b_never) == pytest.approx(
        sum(wins.values()) / 9)
    # ranked as values, the four half pairs would all be lost by A: 2/9 lower
    assert probability_of_improvement([-v for v in a], [-v for v in b]) == pytest.approx(
        (sum(wins.values()) - 2) / 9)
    # nothing censored: P(X < Y) with ties half, as the plain statistic
    x, y = [3.0, 1.0, 2.0], [2.0, 5.0, 2.0]
    none = [False] * 3
    assert censored_improvement(x, none, y, none) == probability_of_improvement(
        [-v for v in x], [-v for v in y])
    low, high = censored_improvement_ci(a, a_never, b, b_never)
    assert 0.0 <= low <= censored_improvement(a, a_never, b, b_never) <= high <= 1.0
    assert censored_improvement_ci(a[:1], a_never[:1], b, b_never) != (low, high)  # 1 run


def test_the_bootstrap_resamples_within_each_stratum():
    # Stratum means can only be 0, 0.5 or 1 and 10, 10.5 or 11, so the pooled mean of any
    # stratified resample lies in [5, 6]; pooling first would allow 0 to 11.
    strata = [[0.0, 1.0, 0.0, 1.0], [10.0, 11.0, 10.0, 11.0]]
    low, high = stratified_ci(strata, statistic=np.mean)
    assert 5 <= low < 5.5 < high <= 6
    pooled_low, pooled_high = stratified_ci([sum(strata, [])], statistic=np.mean)
    assert pooled_low < 4 and pooled_high > 7


def test_the_interval_of_a_mean_matches_the_normal_interval_on_a_large_sample():
    rng = np.random.default_rng(1)
    x = rng.normal(10.0, 2.0, 400)
    low, high = stratified_ci([x], statistic=np.mean, resamples=4000)
    half = 1.96 * x.std() / np.sqrt(len(x))
    assert low == pytest.approx(x.mean() - half, abs=0.03)
    assert high == pytest.approx(x.mean() + half, abs=0.03)
    assert stratified_ci([x]) == stratified_ci([x])  # seeded: the same each time


def test_degenerate_samples_give_a_point_or_no_interval():
    assert stratified_ci([[3.0, 3.0, 3.0]]) == (3.0, 3.0)
    assert all(np.isnan(stratified_ci([[3.0]])))
    assert all(np.isnan(improvement_ci([1.0], [2.0, 3.0])))


def test_improvement_interval_brackets_the_estimate():
    x, y = [1.0, 2.0, 3.0, 5.0], [2.0, 2.0, 0.0, 1.0]
    low, high = improvement_ci(x, y)
    assert low <= probability_of_improvement(x, y) <= high
    assert 0 <= low and high <= 1


def test_the_curve_band_is_per_point_and_collapses_where_seeds_agree():
    curves = np.array([[-200.0, -150.0, -120.0], [-200.0, -130.0, -110.0],
                       [-200.0, -170.0, -100.0]])
    low, high = mean_ci(curves)
    assert low[0] == high[0] == -200.0
    assert np.all(low[1:] <= curves[:, 1:].mean(axis=0))
    assert np.all(curves[:, 1:].mean(axis=0) <= high[1:])
    assert low[1] >= -170 and high[1] <= -130
    one = mean_ci(curves[:1])
    assert np.isnan(one[0]).all() and np.isnan(one[1]).all()


def test_a_diverged_seed_nan_is_left_out_of_every_statistic():
    assert iqm([1.0, 2.0, float("nan"), 3.0]) == pytest.approx(2.0)
    assert np.isnan(iqm([float("nan")]))
    assert stratified_ci([[1.0, 2.0, float("nan"), 3.0]]) == stratified_ci([[1.0, 2.0, 3.0]])
    assert probability_of_improvement([1, 2, 3], [0, 0, float("nan")]) == 1.0
    assert improvement_ci([1, 2, 3], [0, 0, float("nan")]) == (1.0, 1.0)
