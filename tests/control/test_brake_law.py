"""The v^2 / 2d brake law and the brake command."""

import math

import pytest

from avsim.control.brake_law import brake_command, required_decel_mps2


@pytest.mark.parametrize("v, d", [(10.0, 20.0), (23.61, 32.0), (1.0, 0.5)])
def test_required_decel_is_v2_over_2d(v, d):
    assert required_decel_mps2(v, d) == pytest.approx(v * v / (2 * d), rel=1e-12)


@pytest.mark.parametrize("d", [0.0, -3.0])
def test_required_decel_is_inf_at_or_past_target(d):
    assert required_decel_mps2(10.0, d) == math.inf


def test_brake_command_in_range_is_a_over_amax_times_m():
    assert brake_command(4.0, 9.81, 0.8) == pytest.approx(4.0 / 9.81 * 0.8)
    assert brake_command(4.0, 9.81, 1.0) == pytest.approx(4.0 / 9.81)


@pytest.mark.parametrize("a, expected", [(20.0, 1.0), (math.inf, 1.0), (-3.0, 0.0), (0.0, 0.0)])
def test_brake_command_clamps_to_unit_interval(a, expected):
    assert brake_command(a, 9.81, 1.0) == expected


def test_study_consistency_check_85_kmh_in_32_m():
    # ../shared/REFERENCE.md: from 23.6 m/s (85 km/h), ~32 m of braking is ~8.7 m/s^2 (~0.89 g).
    assert 85 / 3.6 == pytest.approx(23.61, abs=0.01)
    a = required_decel_mps2(23.61, 32.0)
    assert a == pytest.approx(8.71, abs=0.01)
    assert a / 9.81 == pytest.approx(0.89, abs=0.005)
    # at that deceleration the stop takes about 2.7 s
    assert 23.61 / a == pytest.approx(2.7, abs=0.05)
