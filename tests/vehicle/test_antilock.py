"""The slip limiter behind anti-lock brakes and traction control, on made-up wheel states."""

import numpy as np
import pytest

from avsim.vehicle.antilock import FAST_REAPPLY_PER_S, HOLD_FRACTION, RELEASE_FACTOR, SlipLimiter

DT = 0.002
REQUEST = np.full(4, 1000.0)
HUB = np.full(4, 20.0)


def test_a_gripping_wheel_gets_the_whole_request():
    limiter = SlipLimiter(0.1)
    out = limiter.limit(REQUEST, REQUEST, np.zeros(4), HUB, DT)
    assert out == pytest.approx(REQUEST)


def test_a_slipping_wheel_is_released_and_the_others_are_not():
    limiter = SlipLimiter(0.1)
    slip = np.array([0.3, 0.0, 0.0, 0.0])
    out = limiter.limit(REQUEST, REQUEST, slip, HUB, DT)
    assert out[0] == pytest.approx(RELEASE_FACTOR * 1000.0)
    assert out[1:] == pytest.approx(REQUEST[1:])


def test_after_release_it_reapplies_fast_up_to_the_hold_then_probes_slowly():
    limiter = SlipLimiter(0.1)
    applied = limiter.limit(REQUEST, REQUEST, np.full(4, 0.3), HUB, DT)  # onset at 1000 N m
    for _ in range(5):  # slip persists: keep releasing
        applied = limiter.limit(REQUEST, applied, np.full(4, 0.3), HUB, DT)
    released = applied.copy()
    applied = limiter.limit(REQUEST, applied, np.zeros(4), HUB, DT)
    assert applied == pytest.approx(released + 1000.0 * FAST_REAPPLY_PER_S * DT)
    while (applied < HOLD_FRACTION * 1000.0).all():
        applied = limiter.limit(REQUEST, applied, np.zeros(4), HUB, DT)
    step = limiter.limit(REQUEST, applied, np.zeros(4), HUB, DT) - applied
    assert (step < 1000.0 * FAST_REAPPLY_PER_S * DT / 4).all()  # the slow probe


def test_near_standstill_the_whole_request_passes_so_the_brake_holds():
    limiter = SlipLimiter(0.1)
    out = limiter.limit(REQUEST, REQUEST, np.full(4, 0.9), np.full(4, 0.5), DT)
    assert out == pytest.approx(REQUEST)
    assert not limiter.active


def test_reset_forgets_the_limits():
    limiter = SlipLimiter(0.1)
    limiter.limit(REQUEST, REQUEST, np.full(4, 0.3), HUB, DT)
    assert limiter.active
    limiter.reset()
    assert not limiter.active
    assert limiter.limit(REQUEST, REQUEST, np.zeros(4), HUB, DT) == pytest.approx(REQUEST)
