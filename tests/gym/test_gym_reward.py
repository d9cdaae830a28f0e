"""The reward's terms, each against its documented definition."""

import pytest

from avsim.gym.reward import (JERK_COST_PER_MPS2, PROGRESS_PER_M, RAN_SIGN_PENALTY, STOP_BONUS, STOP_WINDOW_M,
                              reward_terms)


def _terms(before_m=50.0, after_m=49.0, accel_before=0.0, accel_after=0.0, stopped=False, ran_sign=False):
    return reward_terms(line_dist_before_m=before_m, line_dist_after_m=after_m, accel_before_mps2=accel_before,
                        accel_after_mps2=accel_after, stopped=stopped, ran_sign=ran_sign)


def test_progress_is_paid_per_metre_towards_the_line_and_not_past_it():
    assert _terms(50.0, 48.5).progress == pytest.approx(1.5 * PROGRESS_PER_M)
    assert _terms(0.4, -0.6).progress == pytest.approx(0.4 * PROGRESS_PER_M)  # only the 0.4 m up to the line
    assert _terms(-0.6, -2.0).progress == 0.0
    assert _terms(10.0, 10.5).progress == pytest.approx(-0.5 * PROGRESS_PER_M)  # rolling back


def test_the_stop_bonus_needs_a_stop_within_the_window_before_the_line():
    assert _terms(1.0, 1.0, stopped=True).stop_bonus == STOP_BONUS
    assert _terms(0.0, 0.0, stopped=True).stop_bonus == STOP_BONUS
    assert _terms(STOP_WINDOW_M, STOP_WINDOW_M, stopped=True).stop_bonus == STOP_BONUS
    assert _terms(3.5, 3.5, stopped=True).stop_bonus == 0.0  # too early
    assert _terms(-0.2, -0.2, stopped=True).stop_bonus == 0.0  # past the line
    assert _terms(1.0, 1.0, stopped=False).stop_bonus == 0.0  # still rolling


def test_running_the_sign_costs_the_penalty_and_comfort_the_change_of_acceleration():
    assert _terms(-0.9, -1.1, ran_sign=True).ran_sign == -RAN_SIGN_PENALTY
    assert _terms().ran_sign == 0.0
    assert _terms(accel_before=-2.0, accel_after=-7.0).comfort == pytest.approx(-5.0 * JERK_COST_PER_MPS2)
    assert _terms(accel_before=3.0, accel_after=3.0).comfort == 0.0


def test_the_total_is_the_sum_of_the_terms_and_running_never_pays():
    terms = _terms(0.5, -1.2, accel_before=-1.0, accel_after=2.0, ran_sign=True)
    assert terms.total == pytest.approx(sum(terms.to_dict().values()))
    # The whole default approach (230 m) earns less than running the sign costs.
    assert 230 * PROGRESS_PER_M < RAN_SIGN_PENALTY
