"""Run summaries from hand-made step records, and atomic JSON writing."""

import json
import math

import pytest

from avsim.metrics import (OUTCOMES, STOPPED_BEFORE_SIGN, StepRecord, classify_outcome, rested_beyond_gate, summarise,
                           write_json_atomic)

SIGN_XY = (1.0, -4.0)


def rec(t: float, speed: float = 20.0, brake: float = 0.0, line: float = 50.0, conf: float = 0.0, x: float = 0.0) -> StepRecord:
    """A record whose sign is 1 m beyond the stop line."""
    return StepRecord(
        time_s=t, x_m=x, y_m=-1.75, yaw_rad=0.0, speed_mps=speed, throttle=0.0 if brake else 0.5, brake=brake,
        steer_rad=0.0, stop_line_dist_m=line, sign_dist_m=line + 1.0, est_stop_line_dist_m=None,
        required_decel_mps2=None, top_stop_conf=conf, detections=(),
    )


def run_records(final_line: float):
    records = [
        rec(0.0, speed=20.0, line=60.0),
        rec(0.05, speed=21.0, line=59.0, conf=0.8),
        rec(0.10, speed=22.0, line=58.0, conf=0.9, brake=0.85),
        rec(0.15, speed=15.0, line=30.0, brake=0.85),
    ]
    last = rec(2.60, speed=0.0, line=final_line, brake=0.85)
    return records, last


@pytest.mark.parametrize(
    "final_line, stopped, outcome",
    [
        (2.0, True, "stopped_before_line"),
        (0.0, True, "stopped_before_line"),
        (-0.5, True, "stopped_past_line"),  # between the line and the sign
        (-1.0, True, "stopped_past_line"),  # bumper at the sign
        (-3.0, True, "ran_past_sign"),  # braked, stopped beyond the sign
        (-3.0, False, "ran_past_sign"),  # braked, still rolling beyond the sign
        (2.0, False, "timed_out_before_sign"),  # braked, still rolling when the time ran out
    ],
)
def test_outcome_strings(final_line, stopped, outcome):
    records, last = run_records(final_line)
    result = summarise(records, last, SIGN_XY, stopped, {})
    assert result.outcome == outcome
    assert result.margin_m == final_line
    assert result.sign_margin_m == final_line + 1.0
    assert result.stopped_before_sign == (outcome in ("stopped_before_line", "stopped_past_line"))


@pytest.mark.parametrize("line_m", [60.0, 0.5, -0.9])
def test_a_car_that_never_braked_and_timed_out_before_the_sign_says_so(line_m):
    # A 10 km/h cruise that never reaches the sign before loop.max_time_s: not "ran past".
    records = [rec(0.0, speed=2.8, line=line_m + 1), rec(0.05, speed=2.8, line=line_m + 0.5)]
    result = summarise(records, rec(60.0, speed=2.8, line=line_m), SIGN_XY, False, {})
    assert result.outcome == "timed_out_before_sign"
    assert not result.stopped_before_sign


def test_every_end_of_a_run_has_exactly_one_outcome():
    """The five labels cover every way the loop ends a run: stopped (after braking) or not, braked or
    not, and where the bumper is (before the line, between line and sign, past the sign)."""
    seen = set()
    for stopped in (True, False):
        for braked in (True, False) if not stopped else (True,):  # the loop stops only a car that braked
            for line_m in (5.0, -0.5, -3.0):
                outcome = classify_outcome(stopped=stopped, braked=braked, line_dist_m=line_m, sign_dist_m=line_m + 1.0)
                assert outcome in OUTCOMES
                assert (outcome in STOPPED_BEFORE_SIGN) == (stopped and line_m + 1.0 >= 0)
                seen.add(outcome)
    assert seen == set(OUTCOMES)


def test_time_to_stop_from_first_braking_record():
    records, last = run_records(1.0)
    result = summarise(records, last, SIGN_XY, True, {})
    assert result.time_to_stop_s == pytest.approx(2.60 - 0.10)
    assert result.speed_at_brake_mps == 22.0
    assert result.dist_at_brake_m == 59.0
    assert result.mean_decel_mps2 == pytest.approx(22.0 / 2.5)


def test_first_detection_from_first_positive_confidence():
    records, last = run_records(1.0)
    result = summarise(records, last, SIGN_XY, True, {})
    assert result.first_detection_dist_m == 60.0  # sign distance of the t=0.05 record


def test_no_detection_no_brake_gives_nones():
    records = [rec(0.0, line=10.0), rec(0.05, line=-10.0)]
    last = rec(0.10, line=-20.0)
    result = summarise(records, last, SIGN_XY, False, {})
    assert result.outcome == "never_braked"
    assert result.time_to_stop_s is None
    assert result.first_detection_dist_m is None
    assert result.dist_at_brake_m is None
    assert result.speed_at_brake_mps is None
    assert result.mean_decel_mps2 is None


def test_not_stopped_has_no_time_to_stop_even_if_braking():
    records, last = run_records(1.0)
    result = summarise(records, last, SIGN_XY, False, {})
    assert result.time_to_stop_s is None
    assert result.dist_at_brake_m == 59.0


def test_peak_speed_positions_and_sim_time():
    records, last = run_records(1.0)
    last = rec(2.60, speed=0.0, line=1.0, brake=0.85, x=12.5)
    result = summarise(records, last, SIGN_XY, True, {"k": 1})
    assert result.peak_speed_mps == 22.0
    assert result.stop_position_m == [12.5, -1.75]
    assert result.sign_position_m == [1.0, -4.0]
    assert result.sim_time_s == 2.60
    assert result.config == {"k": 1}


def test_result_json_dict_is_serialisable():
    records, last = run_records(1.0)
    d = summarise(records, last, SIGN_XY, True, {"scenario": {"town": "town07"}}).to_json_dict()
    assert json.loads(json.dumps(d, allow_nan=False))["outcome"] == "stopped_before_line"


# ---- write_json_atomic -----------------------------------------------------------------

def test_write_json_atomic_writes_valid_json_and_no_temp_files(tmp_path):
    path = tmp_path / "sub" / "result.json"
    payload = {"a": 1, "b": [1.5, None], "c": {"d": "x"}}
    write_json_atomic(path, payload)
    assert json.loads(path.read_text()) == payload
    assert [p.name for p in path.parent.iterdir()] == ["result.json"]


def test_write_json_atomic_replaces_existing_file(tmp_path):
    path = tmp_path / "result.json"
    write_json_atomic(path, {"v": 1})
    write_json_atomic(path, {"v": 2})
    assert json.loads(path.read_text()) == {"v": 2}
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_write_json_atomic_refuses_nan_and_leaves_nothing(tmp_path, bad):
    path = tmp_path / "result.json"
    with pytest.raises(ValueError):
        write_json_atomic(path, {"x": bad})
    assert list(tmp_path.iterdir()) == []


def test_write_json_atomic_failure_keeps_previous_file(tmp_path):
    path = tmp_path / "result.json"
    write_json_atomic(path, {"v": 1})
    with pytest.raises(ValueError):
        write_json_atomic(path, {"v": math.nan})
    assert json.loads(path.read_text()) == {"v": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


@pytest.mark.parametrize(("stop_required", "outcome", "margin_m", "trigger_dist_m", "beyond"), [
    (True, "stopped_before_line", 98.2, 40.0, True),    # braked 133 m out on a false stop sign
    (True, "stopped_before_line", 7.3, 40.0, False),    # braked inside the gate for the sign
    (True, "stopped_before_line", 40.0, 40.0, False),   # at the gate's edge: not beyond it
    (True, "stopped_before_line", 98.2, None, False),   # no gate: nothing to be beyond
    (True, "ran_past_sign", -1.7, 40.0, False),
    (False, "phantom_stop", 98.2, 40.0, False),         # no stop required: a phantom stop, counted as such
    (True, "stopped_before_line", None, 40.0, False),
])
def test_a_stop_beyond_the_braking_gate_is_one_that_ended_farther_before_the_line_than_the_gate(
        stop_required, outcome, margin_m, trigger_dist_m, beyond):
    assert rested_beyond_gate(stop_required, outcome, margin_m, trigger_dist_m) is beyond
