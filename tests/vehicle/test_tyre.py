"""The tyre's slip ratio and its friction against slip."""

import numpy as np
import pytest

from avsim.vehicle.tyre import friction_coefficients, slip_ratios


def test_slip_is_zero_rolling_one_locked_negative_spinning():
    hub = np.array([20.0, 20.0, 20.0, 0.0])
    surface = np.array([20.0, 0.0, 30.0, 0.0])
    assert slip_ratios(hub, surface) == pytest.approx([0.0, 1.0, -0.5, 0.0])


def test_slip_denominator_is_floored_so_a_crawl_reads_as_rolling():
    assert slip_ratios(np.array([0.05]), np.array([0.0]), speed_floor_mps=1.0) == pytest.approx([0.05])


def test_friction_is_the_roads_up_to_the_peak_then_falls_to_the_sliding_share():
    slip = np.array([0.0, 0.15, -0.1, 1.0, 0.575])
    mu = friction_coefficients(0.9, slip, peak_slip=0.15, sliding_ratio=0.75)
    assert mu == pytest.approx([0.9, 0.9, 0.9, 0.675, 0.9 * 0.875])


def test_friction_never_falls_below_the_sliding_share():
    assert friction_coefficients(0.5, np.array([5.0, -3.0]), 0.15, 0.75) == pytest.approx([0.375, 0.375])
