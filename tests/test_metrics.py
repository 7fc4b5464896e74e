import math

import pytest

from senbench.analysis.metrics import auc, final_return, steps_to_threshold

STEPS = [0, 100, 200, 300, 400, 500]


def test_final_return_is_the_mean_of_the_last_three_evaluations():
    assert final_return([-200, -150, -120, -110, -100]) == pytest.approx(-110.0)
    assert final_return([-50]) == -50


def test_steps_to_threshold_is_where_the_trailing_mean_stays_above():
    # trailing means of 3: -200, -175, -150, -116.7, -103.3, -96.7 -> stays >= -120 from 300
    returns = [-200, -150, -100, -100, -110, -80]
    assert steps_to_threshold(STEPS, returns, -120) == 300


def test_a_dip_below_the_threshold_restarts_the_count():
    # trailing means: -100, -100, -100, -133.3, -133.3, -133.3 -> ends below: never stable
    returns = [-100, -100, -100, -200, -100, -100]
    assert math.isnan(steps_to_threshold(STEPS, returns, -120))
    # with the last points high enough the curve is stable from the first such point
    assert steps_to_threshold(STEPS, [-100, -100, -100, -200, -100, -100], -140) == 0


def test_not_reached_is_nan_not_an_error():
    assert math.isnan(steps_to_threshold(STEPS, [-200] * 6, -110))


def test_auc_is_the_mean_return_over_the_budget():
    # trapezoid: (0+100)/2*100 + (100+100)/2*100 + 0 ... over 500 frames
    returns = [0, 100, 100, 100, 100, 100]
    assert auc(STEPS, returns) == pytest.approx((50 * 100 + 100 * 400) / 500)
    assert auc([0, 10], [-5, -5]) == -5


def test_nan_returns_never_count_as_reaching_the_threshold():
    assert math.isnan(steps_to_threshold(STEPS, [math.nan] * 6, -110))
    assert math.isnan(steps_to_threshold(STEPS, [-200, -100, -100, -100, -100, math.nan], -110))
    assert math.isnan(steps_to_threshold(STEPS, [-100] * 6, math.nan))
