"""Suspension against closed forms: static sag, bounce frequency and damping, pitch under braking."""

import math

import mujoco
import numpy as np
import pytest

from avsim.config import VehicleConfig
from avsim.vehicle.assembly import load_car
from avsim.vehicle.brake_test import brake_test, make_test_track
from avsim.vehicle.physics import RIDE_HEIGHT_M, Controls
from avsim.vehicle.suspension import GRAVITY_MPS2, WHEELS, corner_springs

DRY = 0.9


@pytest.fixture(scope="module")
def springs():
    config = VehicleConfig()
    return corner_springs(load_car(config), config.suspension_frequency_hz, config.suspension_damping_ratio)


def _settle(config: VehicleConfig, seconds: float = 4.0):
    model, data, car = make_test_track(config, DRY, 0.002)
    car.place(0.0, 0.0, 0.0, 0.0)
    car.apply(Controls(brake=0.3))  # hold the car still while the body settles
    car.advance(round(seconds / 0.002))
    return model, data, car


def test_static_sag_is_m_g_over_4k(springs):
    model, data, car = _settle(VehicleConfig())
    sprung_kg = sum(s.sprung_mass_kg for s in springs.values())
    mean_k = np.mean([s.stiffness_npm for s in springs.values()])
    # Sag: from each spring's free position (springref) to where it rests.
    sag_m = [car.suspension_travel_m()[i] - springs[w].springref_m for i, w in enumerate(WHEELS)]
    assert np.mean(sag_m) == pytest.approx(sprung_kg * GRAVITY_MPS2 / (4 * mean_k), rel=0.10)


def test_the_body_rests_level_at_its_ride_height():
    _, data, car = _settle(VehicleConfig())
    assert abs(math.degrees(car.pitch_rad())) < 0.2
    # The tyres sink a few millimetres into MuJoCo's soft contact.
    assert data.qpos[2] == pytest.approx(RIDE_HEIGHT_M, abs=0.01)


@pytest.mark.parametrize("frequency_hz, damping_ratio", [(1.4, 0.45), (1.2, 0.3)])
def test_bounce_after_a_step_rings_at_the_configured_frequency_and_decays_at_its_damping(frequency_hz, damping_ratio):
    config = VehicleConfig(suspension_frequency_hz=frequency_hz, suspension_damping_ratio=damping_ratio)
    model, data, car = _settle(config)
    rest_z = float(data.qpos[2])
    # Step input: the body is lifted 3 cm from rest, the wheels left on the road, and let go.
    data.qpos[2] += 0.03
    for wheel in WHEELS:
        data.qpos[model.joint(f"car/susp_{wheel}").qposadr[0]] -= 0.03
    mujoco.mj_forward(model, data)
    zs = []
    for _ in range(round(3.0 / 0.002)):
        car.advance(1)
        zs.append(float(data.qpos[2]) - rest_z)
    zs = np.array(zs)
    peaks = [k for k in range(1, len(zs) - 1) if zs[k] > zs[k - 1] and zs[k] >= zs[k + 1] and zs[k] > 1e-4]
    troughs = [k for k in range(1, len(zs) - 1) if zs[k] < zs[k - 1] and zs[k] <= zs[k + 1] and zs[k] < -1e-4]
    extremes = sorted(peaks[:2] + troughs[:2])
    half_periods_s = np.diff(extremes) * 0.002
    damped_hz = 1 / (2 * np.mean(half_periods_s))
    assert damped_hz == pytest.approx(frequency_hz, rel=0.15)
    assert damped_hz == pytest.approx(frequency_hz * math.sqrt(1 - damping_ratio**2), rel=0.10)
    # Logarithmic decrement over the first half period: |x1 / x0| = exp(-pi zeta / sqrt(1 - zeta^2)).
    first, second = zs[extremes[0]], zs[extremes[1]]
    measured_zeta = -math.log(abs(second / first)) / math.sqrt(math.pi**2 + math.log(abs(second / first)) ** 2)
    assert measured_zeta == pytest.approx(damping_ratio, rel=0.25)


def test_the_nose_dives_0_5_to_3_degrees_under_a_full_stop_on_a_dry_road():
    assert 0.5 <= brake_test(VehicleConfig(), DRY).peak_pitch_deg <= 3.0


def test_the_body_settles_back_level_once_the_car_is_at_rest():
    model, data, car = make_test_track(VehicleConfig(), DRY, 0.002)
    car.place(0.0, 0.0, 0.0, 85 / 3.6)
    pitches, speeds = [], []
    for _ in range(round(6.0 / 0.05)):
        car.apply(Controls(brake=1.0))
        car.advance(25)
        pitches.append(math.degrees(car.pitch_rad()))
        speeds.append(car.speed_mps())
    stopped = int(np.argmax(np.array(speeds) < 0.1))
    assert max(pitches) > 0.5  # it did dive
    assert abs(pitches[-1]) < 0.2  # 3 s after the stop (at 20 Hz: index 60 past it) it is level again
    assert len(pitches) - stopped >= 40


def test_springs_share_the_sprung_mass_and_ride_at_one_frequency(springs):
    compiled = load_car(VehicleConfig()).compile()
    assert sum(s.sprung_mass_kg for s in springs.values()) == pytest.approx(compiled.body_mass[compiled.body("car").id])
    for spring in springs.values():
        assert math.sqrt(spring.stiffness_npm / spring.sprung_mass_kg) / (2 * math.pi) == pytest.approx(1.4)
        assert spring.static_sag_m == pytest.approx(GRAVITY_MPS2 / (2 * math.pi * 1.4) ** 2)
