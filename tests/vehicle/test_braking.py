"""Braking against closed forms: full stops on dry, wet and snowy roads, anti-lock brakes,
a brake that holds, a brake proportional to its command, and cruise."""

import numpy as np
import pytest

from avsim.config import VehicleConfig
from avsim.loop import ClosedLoop
from avsim.vehicle.brake_test import brake_test, make_test_track
from avsim.vehicle.physics import Controls
from avsim.vehicle.suspension import GRAVITY_MPS2
from helpers import make_config

V0_MPS = 85 / 3.6
DRY, WET, SNOW = 0.9, 0.5, 0.2


@pytest.fixture(scope="module")
def dry_stop():
    return brake_test(VehicleConfig(), DRY, V0_MPS)


def test_full_brake_on_dry_road_stops_from_85_kmh_like_a_car(dry_stop):
    assert 2.5 <= dry_stop.stop_time_s <= 3.0
    assert 8.0 <= dry_stop.mean_decel_mps2 <= 9.5


def test_dry_braking_distance_is_v_squared_over_2a(dry_stop):
    assert dry_stop.stop_dist_m == pytest.approx(V0_MPS**2 / (2 * dry_stop.mean_decel_mps2), rel=0.03)


def test_no_wheel_locks_and_the_car_keeps_straight_under_full_brake(dry_stop):
    assert dry_stop.max_brake_slip <= 0.2
    assert dry_stop.max_yaw_deg <= 2.0


def test_abs_efficiency_on_dry_road_is_that_of_a_car(dry_stop):
    # With ABS a car turns 0.85-1.0 of the road's grip into deceleration (REFERENCE.md).
    assert 0.85 <= dry_stop.efficiency <= 1.0


@pytest.mark.parametrize("road_mu", [WET, SNOW])
def test_full_brake_deceleration_is_mu_g_eta_on_wet_and_snow(dry_stop, road_mu):
    stop = brake_test(VehicleConfig(), road_mu, V0_MPS)
    eta = dry_stop.efficiency  # measured on the dry road, stated in docs/vehicle.md
    assert stop.mean_decel_mps2 == pytest.approx(road_mu * GRAVITY_MPS2 * eta, rel=0.15)
    assert stop.max_brake_slip <= 0.2


def test_stopping_distance_scales_as_one_over_mu():
    ratio = brake_test(VehicleConfig(), 0.45, V0_MPS).stop_dist_m / brake_test(VehicleConfig(), 0.9, V0_MPS).stop_dist_m
    assert 1.8 <= ratio <= 2.2


@pytest.mark.parametrize("road_mu", [DRY, WET])
def test_locked_wheels_slide_and_stop_later_than_abs(road_mu):
    with_abs = brake_test(VehicleConfig(), road_mu, V0_MPS)
    locked = brake_test(VehicleConfig(abs_enabled=False), road_mu, V0_MPS)
    assert locked.max_brake_slip > 0.9  # the wheels lock
    assert locked.stop_dist_m > 1.1 * with_abs.stop_dist_m  # and slide on the lower sliding friction


def test_below_the_tyres_limit_deceleration_is_proportional_to_the_brake_command():
    light = brake_test(VehicleConfig(), DRY, 15.0, brake=0.3)
    firm = brake_test(VehicleConfig(), DRY, 15.0, brake=0.6)
    assert light.max_brake_slip < 0.05 and firm.max_brake_slip < 0.05  # the anti-lock never acted
    assert firm.mean_decel_mps2 / light.mean_decel_mps2 == pytest.approx(2.0, rel=0.1)


def _trace(brake: float, speed_mps: float, seconds: float):
    """(times [s], x [m], speed [m/s]) at every physics step of a straight stop on a dry track."""
    model, _, car = make_test_track(VehicleConfig(), DRY, 0.002)
    car.place(0.0, 0.0, 0.0, speed_mps)
    times, xs, speeds = [], [], []
    for k in range(round(seconds / 0.002)):
        if k % 25 == 0:
            car.apply(Controls(brake=brake))  # refreshes the drag, as the loop does each control step
        car.advance(1)
        times.append((k + 1) * 0.002)
        xs.append(car.position_xy_m()[0])
        speeds.append(car.speed_mps())
    return np.array(times), np.array(xs), np.array(speeds)


def test_brake_does_not_fade_as_the_wheels_slow():
    times, _, speeds = _trace(0.5, 20.0, 6.0)

    def decel_between(v_hi, v_lo):
        k0, k1 = np.argmax(speeds <= v_hi), np.argmax(speeds <= v_lo)
        return (speeds[k0] - speeds[k1]) / (times[k1] - times[k0])
    # A viscous damper would brake ~10x less at 1-3 m/s than at 20-15 m/s; a friction brake
    # loses only the drag's share (about 0.15 m/s^2 at 20 m/s).
    assert decel_between(3.0, 1.0) == pytest.approx(decel_between(18.0, 15.0), rel=0.05)


def test_brake_holds_the_car_at_rest():
    times, xs, speeds = _trace(1.0, 10.0, 5.0)
    stopped_at = times[np.argmax(speeds < 0.1)]
    at_rest = times >= stopped_at + 0.5
    assert np.ptp(xs[at_rest]) < 0.01


def test_cruise_holds_85_kmh_within_1_kmh_for_10_s():
    loop = ClosedLoop(make_config(scenario={"start_speed_kmh": 85.0, "start_dist_m": 300.0}, policy={"name": "autopilot"}))
    speeds_kmh = [loop.step().speed_mps * 3.6 for _ in range(int(10.0 / loop.config.loop.control_dt_s))]
    loop.close()
    assert not loop.braking
    assert max(abs(s - 85.0) for s in speeds_kmh) <= 1.0


def test_speed_controller_reaches_85_kmh_from_rest_without_overshoot():
    loop = ClosedLoop(make_config(scenario={"start_dist_m": 300.0}, policy={"name": "autopilot"}))
    speeds_kmh = [loop.step().speed_mps * 3.6 for _ in range(int(14.0 / loop.config.loop.control_dt_s))]
    loop.close()
    reached = next(i for i, s in enumerate(speeds_kmh) if s >= 84.0)
    assert reached * loop.config.loop.control_dt_s < 10.0
    assert max(speeds_kmh) <= 86.0
    assert abs(speeds_kmh[-1] - 85.0) <= 1.0


def _accelerate_on_snow(traction_control: bool) -> tuple[float, float]:
    """Full throttle for 3 s from 5 m/s on snow: (speed gained [m/s], worst driven-wheel spin)."""
    _, _, car = make_test_track(VehicleConfig(traction_control_enabled=traction_control), SNOW, 0.002)
    car.place(0.0, 0.0, 0.0, 5.0)
    worst_spin = 0.0
    for _ in range(round(3.0 / 0.05)):
        car.apply(Controls(throttle=1.0))
        car.advance(25)
        worst_spin = max(worst_spin, float(-car.wheel_slips()[2:].min()))
    return car.speed_mps() - 5.0, worst_spin


def test_traction_control_keeps_the_driven_wheels_from_spinning_on_snow():
    gained_tc, spin_tc = _accelerate_on_snow(True)
    gained_free, spin_free = _accelerate_on_snow(False)
    assert spin_free > 1.0  # 900 N m per rear wheel spins them on snow
    assert spin_tc <= 0.2
    assert gained_tc > 1.2 * gained_free  # a gripping tyre pulls harder than a spinning one
    # Rear-wheel drive on mu = 0.2 can pull at most about half the car's weight times mu.
    assert gained_tc / 3.0 <= 0.6 * SNOW * GRAVITY_MPS2
