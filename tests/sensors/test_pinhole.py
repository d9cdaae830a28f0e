"""Pinhole range: d = H_real * f / h_bbox."""

import math

import pytest

from avsim.sensors.pinhole import pinhole_distance_m

F_PX = (480 / 2) / math.tan(math.radians(15))


@pytest.mark.parametrize("h", [10.0, 17.0, 45.5, 200.0])
def test_pinhole_distance_is_h_real_f_over_h(h):
    assert pinhole_distance_m(0.762, F_PX, h) == pytest.approx(0.762 * F_PX / h, rel=1e-12)


def test_pinhole_distance_halves_when_box_doubles():
    assert pinhole_distance_m(0.762, F_PX, 40.0) == pytest.approx(pinhole_distance_m(0.762, F_PX, 20.0) / 2)


@pytest.mark.parametrize("h", [0.0, -1.0])
def test_pinhole_distance_rejects_non_positive_box(h):
    with pytest.raises(ValueError):
        pinhole_distance_m(0.762, F_PX, h)
