"""Result keys for availability and comfort: max_brake, stop_required, the outcomes of a run that
had no stop to make, the phantom-brake rule, and the peak deceleration and jerk against closed forms."""

import pytest

from avsim.metrics import (NO_STOP_OUTCOMES, OUTCOMES, PHANTOM_BRAKE_LEVEL, StepRecord, classify_outcome, comfort_peaks,
                           summarise)

SIGN_XY = (1.0, -4.0)
DT = 0.05


def rec(t: float, speed: float, brake: float = 0.0, line: float = 50.0) -> StepRecord:
    return StepRecord(time_s=t, x_m=-line, y_m=-1.75, yaw_rad=0.0, speed_mps=speed, throttle=0.0, brake=brake, steer_rad=0.0,
                      stop_line_dist_m=line, sign_dist_m=line + 1.0, est_stop_line_dist_m=None, required_decel_mps2=None,
                      top_stop_conf=0.0, detections=())


def test_max_brake_is_the_largest_command_and_stop_required_is_carried():
    records = [rec(0.0, 20.0), rec(0.05, 20.0, brake=0.2), rec(0.10, 19.0, brake=0.6), rec(0.15, 18.0, brake=0.4)]
    result = summarise(records, rec(0.20, 17.0, line=-45.0), SIGN_XY, False, {}, stop_required=False)
    assert result.max_brake == 0.6 and result.stop_required is False
    assert result.phantom_brake
    assert result.to_json_dict()["max_brake"] == 0.6 and result.to_json_dict()["stop_required"] is False


@pytest.mark.parametrize("max_brake, stop_required, phantom", [
    (PHANTOM_BRAKE_LEVEL, False, False),  # "above 0.3"
    (0.31, False, True),
    (1.0, True, False),  # braking where a stop is required is no phantom
    (0.0, False, False),
])
def test_a_phantom_brake_is_a_brake_above_the_level_where_no_stop_is_required(max_brake, stop_required, phantom):
    records = [rec(0.0, 20.0), rec(0.05, 20.0, brake=max_brake)]
    result = summarise(records, rec(0.1, 19.0, line=-45.0), SIGN_XY, False, {}, stop_required=stop_required)
    assert result.phantom_brake is phantom


def test_every_end_of_a_run_with_no_stop_required_has_one_no_stop_outcome():
    seen = set()
    for stopped, braked in ((True, True), (False, True), (False, False)):
        for line_m in (5.0, -0.5, -45.0):
            outcome = classify_outcome(stopped=stopped, braked=braked, line_dist_m=line_m, sign_dist_m=line_m + 1.0,
                                       stop_required=False)
            assert outcome in NO_STOP_OUTCOMES
            seen.add(outcome)
    assert seen == set(NO_STOP_OUTCOMES)
    # A car that drives through an empty junction is correct; a stop there is a phantom stop.
    assert classify_outcome(stopped=False, braked=False, line_dist_m=-45.0, sign_dist_m=-44.0, stop_required=False) == "drove_through"
    assert classify_outcome(stopped=True, braked=True, line_dist_m=20.0, sign_dist_m=21.0, stop_required=False) == "phantom_stop"


def test_stop_required_runs_keep_their_five_labels():
    assert classify_outcome(stopped=False, braked=False, line_dist_m=-45.0, sign_dist_m=-44.0) == "never_braked"
    assert "drove_through" not in OUTCOMES and "phantom_stop" not in OUTCOMES


def test_constant_deceleration_gives_its_value_and_the_onset_jerk_of_one_step():
    # Cruise at 20 m/s, then a constant 8 m/s^2 from t = 0.1 s: the speed falls 0.4 m/s a step.
    a, v0 = 8.0, 20.0
    speeds = [v0, v0] + [v0 - a * DT * k for k in range(1, 30)]
    records = [rec(DT * k, v, brake=0.8 if k >= 1 else 0.0) for k, v in enumerate(speeds)]
    decel, jerk = comfort_peaks(records[:-1], records[-1])
    assert decel == pytest.approx(a)
    assert jerk == pytest.approx(a / DT)  # from 0 to 8 m/s^2 within one 50 ms step


def test_the_stop_counts_in_the_jerk_and_a_car_that_never_braked_has_none():
    records = [rec(0.0, 1.2, brake=0.5), rec(DT, 0.8, brake=0.5), rec(2 * DT, 0.4, brake=0.5)]
    decel, jerk = comfort_peaks(records, rec(3 * DT, 0.0, brake=0.5))
    assert decel == pytest.approx(8.0) and jerk == pytest.approx(0.0, abs=1e-9)  # 8 m/s^2 to the end
    records = [rec(0.0, 1.2, brake=0.5), rec(DT, 0.8, brake=0.5), rec(2 * DT, 0.4, brake=0.5), rec(3 * DT, 0.0, brake=0.5)]
    assert comfort_peaks(records, rec(4 * DT, 0.0, brake=0.5))[1] == pytest.approx(8.0 / DT)  # standstill sheds it at once
    assert comfort_peaks([rec(0.0, 20.0), rec(DT, 20.0)], rec(2 * DT, 20.0)) == (None, None)
