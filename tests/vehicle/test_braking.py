"""Vehicle dynamics against closed forms: full braking, a brake that holds, cruise."""

import math

import mujoco
import numpy as np
import pytest

from avsim.loop import ClosedLoop
from avsim.vehicle.physics import Controls
from helpers import make_config

V0_MPS = 85 / 3.6


def _brake_from(speed_mps: float, brake: float = 1.0, hold_s: float = 0.0):
    """Full-stop trace: (times [s], x [m], speed [m/s], yaw [rad]) sampled every physics step."""
    loop = ClosedLoop(make_config())
    loop.vehicle.place(-150.0, loop.scene.layout.lane_center_y_m, 0.0, speed_mps)
    loop.vehicle.apply(Controls(brake=brake))
    dt = loop.model.opt.timestep
    times, xs, speeds, yaws = [0.0], [loop.vehicle.position_xy_m()[0]], [speed_mps], [0.0]
    stopped_at = None
    while stopped_at is None or times[-1] < stopped_at + hold_s:
        mujoco.mj_step(loop.model, loop.data)
        times.append(times[-1] + dt)
        xs.append(loop.vehicle.position_xy_m()[0])
        speeds.append(loop.vehicle.speed_mps())
        yaws.append(loop.vehicle.yaw_rad())
        if stopped_at is None and speeds[-1] < 0.1:
            stopped_at = times[-1]
        # Drag is applied per control step in the loop; refresh it at the same rate here.
        if len(times) % loop.config.loop.substeps == 0:
            loop.vehicle.apply(Controls(brake=brake))
        assert times[-1] < 20, "the car never stopped"
    loop.close()
    return np.array(times), np.array(xs), np.array(speeds), np.array(yaws), stopped_at


@pytest.fixture(scope="module")
def full_brake():
    return _brake_from(V0_MPS, hold_s=2.0)


def test_full_brake_stops_from_85_kmh_in_study_time(full_brake):
    _, _, _, _, stop_time_s = full_brake
    assert 2.5 <= stop_time_s <= 3.0


def test_full_brake_deceleration_is_that_of_a_car_on_dry_asphalt(full_brake):
    _, _, _, _, stop_time_s = full_brake
    assert 8.0 <= V0_MPS / stop_time_s <= 9.5


def test_braking_distance_matches_v_squared_over_2a(full_brake):
    times, xs, speeds, _, stop_time_s = full_brake
    k_stop = int(np.argmax(times >= stop_time_s))
    mean_decel = V0_MPS / stop_time_s
    assert xs[k_stop] - xs[0] == pytest.approx(V0_MPS**2 / (2 * mean_decel), rel=0.03)


def test_car_keeps_straight_under_full_brake(full_brake):
    _, _, _, yaws, _ = full_brake
    assert np.abs(yaws).max() < math.radians(2.0)


def test_brake_does_not_fade_as_the_wheels_slow(full_brake):
    times, _, speeds, _, _ = full_brake
    def decel_between(v_hi, v_lo):
        k0, k1 = np.argmax(speeds <= v_hi), np.argmax(speeds <= v_lo)
        return (speeds[k0] - speeds[k1]) / (times[k1] - times[k0])
    # A viscous damper would brake ~10x less at 1-3 m/s than at 20-15 m/s; a friction brake
    # loses only the drag's share (about 0.15 m/s^2 at 20 m/s).
    assert decel_between(3.0, 1.0) == pytest.approx(decel_between(20.0, 15.0), rel=0.05)


def test_brake_holds_the_car_at_rest(full_brake):
    times, xs, _, _, stop_time_s = full_brake
    at_rest = times >= stop_time_s + 0.5
    assert np.ptp(xs[at_rest]) < 0.01


def test_half_brake_decelerates_about_half_as_hard():
    _, _, _, _, full_s = _brake_from(15.0, brake=1.0)
    _, _, _, _, half_s = _brake_from(15.0, brake=0.5)
    assert half_s / full_s == pytest.approx(2.0, rel=0.1)


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
