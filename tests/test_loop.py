"""The closed loop over every registered town, placement and policy, at 85 km/h."""

import math

import numpy as np
import pytest

from avsim.control.policies import POLICIES
from avsim.errors import PhysicsError
from avsim.loop import ClosedLoop
from avsim.runner import run_config
from avsim.world.towns import PLACEMENTS, TOWNS
from helpers import CRUISE_START, make_config

CELLS = [(town, placement) for town in TOWNS.names() for placement in PLACEMENTS.names()]
ONE_CAMERA_POLICIES = ["baseline", "adjusted"]
TWO_CAMERA_POLICIES = ["side_camera", "combined"]


@pytest.mark.parametrize("town,placement", CELLS)
def test_autopilot_stops_within_1_5_m_before_the_stop_line(study_run, town, placement):
    result = study_run(town, placement, "autopilot")
    assert result.outcome == "stopped_before_line"
    assert 0.0 <= result.margin_m <= 1.5


def _assert_stopped_before_the_sign_at_85_kmh(result, policy: str) -> None:
    assert result.sign_margin_m > 0, f"{policy} ran {-result.sign_margin_m:.1f} m past the sign"
    assert result.time_to_stop_s is not None
    assert result.peak_speed_mps * 3.6 == pytest.approx(85.0, abs=1.0)


@pytest.mark.parametrize("policy", ONE_CAMERA_POLICIES)
@pytest.mark.parametrize("town,placement", CELLS)
def test_oracle_policies_stop_before_the_sign(study_run, town, placement, policy):
    _assert_stopped_before_the_sign_at_85_kmh(study_run(town, placement, policy), policy)


# The two-camera policies render twice a step, so they run in `make test`'s slow pass, and from CRUISE_START rather
# than the study's start (Town10 about 15 CPU-s a run from rest on a 2-core AVX2 machine, about half that from it).
@pytest.mark.slow
@pytest.mark.parametrize("policy", TWO_CAMERA_POLICIES)
@pytest.mark.parametrize("town,placement", CELLS)
def test_two_camera_oracle_policies_stop_before_the_sign_from_cruise(town, placement, policy):
    config = make_config(scenario={"town": town, "placement": placement, **CRUISE_START}, policy={"name": policy})
    result = run_config(config)[0]
    _assert_stopped_before_the_sign_at_85_kmh(result, policy)
    assert result.first_detection_dist_m < CRUISE_START["start_dist_m"] - 10.0  # the sign was first seen on the way


@pytest.mark.parametrize("town,placement", CELLS)
def test_baseline_stops_a_few_metres_before_the_sign_like_the_study(study_run, town, placement):
    # The study's clean-sign stop was 4.3 m before the sign.
    assert 2.0 <= study_run(town, placement, "baseline").sign_margin_m <= 8.0


def test_full_brake_defence_stops_in_the_study_time(study_run):
    result = study_run("town07", "standard", "side_camera")
    # The study measured 2.55-2.75 s from the brake to a full stop.
    assert 2.3 <= result.time_to_stop_s <= 3.2


def test_the_oracle_sees_as_far_as_the_detector_and_braking_begins_at_the_gate(study_run):
    result = study_run("town07", "standard", "baseline")
    # The oracle's range is calibrated to the detector's: 6.8 px, about 100 m of camera depth.
    assert 95.0 <= result.first_detection_dist_m <= 105.0
    # The policy's gate (40 m to the stop line, 41 m to the sign) decides when braking begins.
    assert 39.0 <= result.dist_at_brake_m <= 42.5


def test_adjusted_braking_brakes_harder_when_closer():
    loop = ClosedLoop(make_config(policy={"name": "adjusted"}))
    loop.run()
    braking = [r for r in loop.records if r.brake > 0 and r.brake < 1]
    loop.close()
    assert len(braking) > 10
    # Required deceleration follows v^2 / 2d on the estimate, the law the study used.
    for r in braking:
        d = r.est_stop_line_dist_m - loop.config.policy.stop_margin_m
        assert r.required_decel_mps2 == pytest.approx(r.speed_mps**2 / (2 * d), rel=1e-9)


def test_same_config_and_seed_give_bit_identical_results():
    config = make_config(scenario={"town": "town03", "placement": "far", "seed": 3}, policy={"name": "adjusted"})
    first, _ = run_config(config)
    second, _ = run_config(config)
    assert first.stop_position_m == second.stop_position_m
    assert first.to_json_dict() == second.to_json_dict()


def test_different_seeds_start_from_different_positions():
    a = ClosedLoop(make_config(scenario={"seed": 0}))
    b = ClosedLoop(make_config(scenario={"seed": 1}))
    assert a.vehicle.position_xy_m()[0] != b.vehicle.position_xy_m()[0]
    a.close(), b.close()


@pytest.mark.parametrize("policy", POLICIES.names())
@pytest.mark.parametrize("town,placement", CELLS)
def test_every_registry_entry_builds_and_steps_without_nan(town, placement, policy):
    loop = ClosedLoop(make_config(scenario={"town": town, "placement": placement, "start_speed_kmh": 85.0}, policy={"name": policy}))
    for _ in range(10):
        loop.step()
    loop.close()
    assert np.isfinite(loop.data.qpos).all() and np.isfinite(loop.data.qvel).all()


def test_diverging_physics_ends_the_run_with_a_clear_error():
    loop = ClosedLoop(make_config(policy={"name": "autopilot"}))
    loop.step()
    loop.data.qvel[0] = math.nan
    with pytest.raises(PhysicsError, match="diverged"):
        loop.step()
    loop.close()


def test_run_without_braking_ends_once_well_past_the_sign():
    # A detection range of 1000 px is never reached: the car runs the sign.
    result, _ = run_config(make_config(perception={"oracle_min_box_height_px": 1000.0}, scenario={"start_speed_kmh": 85.0, "start_dist_m": 80.0}))
    assert result.outcome == "never_braked"
    assert result.time_to_stop_s is None and result.first_detection_dist_m is None
    assert result.sign_margin_m < -30


def test_a_slow_car_the_time_limit_stops_before_the_sign_has_timed_out_not_run_past():
    # 10 km/h for 3 s covers about 8 m of the 60: the run ends on the clock, far before the sign.
    result, _ = run_config(make_config(scenario={"speed_kmh": 10.0, "start_dist_m": 60.0}, loop={"max_time_s": 3.0}))
    assert result.outcome == "timed_out_before_sign"
    assert result.sign_margin_m > 40 and result.dist_at_brake_m is None
    assert result.sim_time_s == pytest.approx(3.0)
