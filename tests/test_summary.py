"""The printed summary names the outcome with the JSON's own word, for every outcome there is."""

import pytest

from avsim.config import SimConfig
from avsim.metrics import OUTCOMES, StepRecord, summarise
from avsim.summary import format_summary, outcome_line

CONFIG = SimConfig().to_dict()


def rec(t: float, line_m: float, speed_mps: float = 10.0, brake: float = 0.0) -> StepRecord:
    return StepRecord(time_s=t, x_m=-line_m, y_m=-1.75, yaw_rad=0.0, speed_mps=speed_mps, throttle=0.0, brake=brake,
                      steer_rad=0.0, stop_line_dist_m=line_m, sign_dist_m=line_m + 1.0, est_stop_line_dist_m=None,
                      required_decel_mps2=None, top_stop_conf=0.0, detections=())


# (end bumper to stop line [m], stopped, braked) -> the outcome each must give.
ENDS = {
    "stopped_before_line": (3.0, True, True),
    "stopped_past_line": (-0.4, True, True),
    "ran_past_sign": (-4.0, False, True),
    "never_braked": (-41.0, False, False),
    "timed_out_before_sign": (64.6, False, False),
}


@pytest.mark.parametrize("outcome", OUTCOMES)
def test_the_summary_line_starts_with_the_outcome_the_json_holds(outcome):
    line_m, stopped, braked = ENDS[outcome]
    records = [rec(0.0, 80.0), rec(0.05, 79.0, brake=0.85 if braked else 0.0)]
    result = summarise(records, rec(60.0, line_m, 0.0 if stopped else 2.8), (1.0, -5.5), stopped, CONFIG)
    assert result.outcome == outcome
    printed = format_summary(result, wall_s=1.0).splitlines()[1].split()
    assert printed[:2] == ["outcome", f"{outcome}:"]


def test_a_timed_out_run_says_where_it_was_and_whether_it_had_braked():
    for braked, expected in ((False, "never braked"), (True, "still rolling, braking since 80.0 m before the sign")):
        records = [rec(0.0, 80.0), rec(0.05, 79.0, brake=0.3 if braked else 0.0)]
        result = summarise(records, rec(60.0, 64.6, 2.8, brake=0.3 if braked else 0.0), (1.0, -5.5), False, CONFIG)
        assert outcome_line(result) == f"timed_out_before_sign: the 60 s time limit ended the run 65.6 m before the sign; {expected}"


@pytest.mark.parametrize("outcome, line_m, stopped, braked", [
    ("drove_through", -41.0, False, False),
    ("phantom_stop", 30.0, True, True),
])
def test_a_run_that_had_no_stop_to_make_prints_its_own_outcome(outcome, line_m, stopped, braked):
    records = [rec(0.0, 80.0), rec(0.05, 79.0, brake=0.85 if braked else 0.0)]
    result = summarise(records, rec(9.0, line_m, 0.0 if stopped else 20.0), (1.0, -5.5), stopped, CONFIG, stop_required=False)
    assert result.outcome == outcome
    printed = format_summary(result, wall_s=1.0).splitlines()[1].split()
    assert printed[:2] == ["outcome", f"{outcome}:"]


@pytest.mark.parametrize("perception, header", [
    ({"kind": "detector", "detector_precision": "auto"}, "perception detector (fp32)"),
    ({"kind": "detector", "detector_precision": "fp32"}, "perception detector (fp32)"),
    ({"kind": "ensemble", "ensemble_members": ["detector", "coco"], "detector_precision": "auto"},
     "perception ensemble (detector fp32, coco fp32) /"),
    ({"kind": "ensemble", "ensemble_members": ["coco", "yolo"]}, "perception ensemble (coco fp32, yolo fp32) /"),
    ({"kind": "coco"}, "perception coco (fp32) /"),
    ({"kind": "yolo", "yolo_precision": "fp32"}, "perception yolo (fp32) /"),
    ({"kind": "nanodet"}, "perception nanodet /"),
    ({"kind": "oracle"}, "perception oracle /"),
])
def test_the_header_names_the_arithmetic_each_network_ran_in(monkeypatch, perception, header):
    # On a CPU without bf16 "auto" is fp32; the config keeps "auto", the summary says what ran.
    monkeypatch.setattr("avsim.perception.cpu_bf16.onednn_runs_bf16", lambda: False)
    config = SimConfig().to_dict()
    config["perception"] = {**config["perception"], **perception}
    records = [rec(0.0, 80.0), rec(0.05, 79.0, brake=0.85)]
    result = summarise(records, rec(5.0, 3.0, 0.0), (1.0, -5.5), True, config)
    assert header in format_summary(result, wall_s=1.0).splitlines()[0]
