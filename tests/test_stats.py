"""Wilson intervals and the rates reports print with them."""

import math

import pytest

from avsim.stats import rate_with_interval, sign_test_p, wilson_interval


def test_wilson_interval_matches_the_closed_form_and_stays_in_zero_one():
    # 19 of 20: centre (0.95 + 1.96^2/40) / (1 + 1.96^2/20), the textbook 0.764-0.991
    lo, hi = wilson_interval(19, 20)
    assert lo == pytest.approx(0.7639, abs=1e-3) and hi == pytest.approx(0.9911, abs=1e-3)
    lo, hi = wilson_interval(20, 20)
    assert hi == 1.0 and 0.83 < lo < 0.84
    assert wilson_interval(0, 10)[0] == 0.0
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    # more samples, narrower interval around the same proportion
    assert (lambda a, b: a[1] - a[0] < b[1] - b[0])(wilson_interval(950, 1000), wilson_interval(19, 20))


def test_rate_with_interval_prints_count_and_interval():
    assert rate_with_interval(5, 5) == "5/5 (0.57–1.00)"
    assert rate_with_interval(0, 0) == "–"


@pytest.mark.parametrize("n", range(1, 60))
def test_wilson_bounds_are_exactly_0_and_1_at_no_hits_and_all_hits(n):
    assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
    low, high = wilson_interval(n // 2, n)
    assert low <= (n // 2) / n <= high


def test_the_sign_test_is_the_exact_binomial_tail_both_ways():
    assert sign_test_p(0, 0) == 1.0
    assert sign_test_p(10, 0) == pytest.approx(2 / 2 ** 10)  # 0.00195
    assert sign_test_p(0, 10) == sign_test_p(10, 0)
    assert sign_test_p(8, 1) == pytest.approx(2 * (1 + 9) / 2 ** 9)  # 0.039
    assert sign_test_p(3, 3) == 1.0  # capped: the two tails overlap
