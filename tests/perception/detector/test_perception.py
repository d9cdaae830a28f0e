"""The shipped detector as the car's perception: boxes on fresh renders, bad weights, closed-loop stops."""

import functools

import pytest

from avsim import cli
from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.base import Perception
from avsim.perception.detector.weights import SHIPPED_WEIGHTS
from avsim.perception.factory import build_perception
from avsim.runner import run_config
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import PLACEMENTS, TOWNS
from helpers import CRUISE_START

CELLS = [(town, placement) for town in TOWNS.names() for placement in PLACEMENTS.names()]


def test_detector_is_the_default_perception_and_its_weights_are_shipped():
    assert SimConfig().perception.kind == "detector"
    assert SHIPPED_WEIGHTS.is_file() and SHIPPED_WEIGHTS.stat().st_size < 20e6


@pytest.mark.parametrize("town", TOWNS.names())
def test_clean_stop_sign_at_30_m_is_detected_within_3_px_of_the_segmentation_box(town):
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}, "perception": {"kind": "detector"}}))
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - 30.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        oracle = build_perception(PerceptionConfig(kind="oracle"), loop.config.camera, loop.model, loop.scene)
        truth = [d for d in oracle.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
        found = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
    finally:
        loop.close()
    assert len(truth) == 1
    assert found, "the detector missed the clean stop sign at 30 m"
    best = found[0]
    assert best.confidence >= 0.75  # the study's clean-sign confidence
    assert max(abs(a - b) for a, b in zip(best.box_xyxy_px, truth[0].box_xyxy_px)) <= 3.0


@pytest.mark.parametrize("content", [b"", b"not a torch file", b"PK\x03\x04 truncated zip"], ids=["empty", "text", "torn_zip"])
def test_corrupt_weights_are_refused_with_one_line_and_exit_2(tmp_path, capsys, content):
    weights = tmp_path / "bad.pt"
    weights.write_bytes(content)
    out = tmp_path / "out.json"
    code = cli.main(["run", "--perception", "detector", "--set", f"perception.weights_path='{weights}'", "--json", str(out)])
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2 and len(lines) == 1, captured.err
    assert "bad.pt" in lines[0] and "avsim detector train" in lines[0]
    assert not out.exists()


def test_missing_weights_say_how_to_train_them(tmp_path, capsys):
    code = cli.main(["run", "--perception", "detector", "--set", f"perception.weights_path='{tmp_path / 'none.pt'}'"])
    err = capsys.readouterr().err
    assert code == 2 and "missing" in err and "avsim detector train" in err


# The closed-loop runs below start from CRUISE_START, not the study's start (a one-camera run 6-10 CPU-s against
# 12-15 on a 2-core AVX2 machine). The study's own starts are pinned by tests/experiments/test_study_outcomes.py.


@functools.lru_cache(maxsize=None)
def _clean_sign_approach(town: str, placement: str, policy: str):
    """The clean-sign run of `policy` with the own detector at 85 km/h from CRUISE_START, seed 0 (cached: two
    tests read the baseline's)."""
    config = with_overrides(SimConfig(), {"scenario": {"town": town, "placement": placement, **CRUISE_START},
                                          "policy": {"name": policy}, "perception": {"kind": "detector"}})
    return run_config(config)[0]


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["baseline", "adjusted", "side_camera"])
@pytest.mark.parametrize("town,placement", CELLS)
def test_detector_policies_stop_before_the_clean_sign(town, placement, policy):
    result = _clean_sign_approach(town, placement, policy)
    assert result.sign_margin_m > 0, f"{policy} ran {-result.sign_margin_m:.1f} m past the sign"
    assert result.peak_speed_mps * 3.6 == pytest.approx(85.0, abs=1.0)
    assert result.first_detection_dist_m < CRUISE_START["start_dist_m"] - 10.0  # the sign was first seen on the way


@pytest.mark.slow
@pytest.mark.parametrize("town,placement", CELLS)
def test_detector_baseline_stops_a_few_metres_before_the_sign_like_the_study(town, placement):
    # The study's clean-sign baseline stop was 4.3 m before the sign.
    assert 1.0 <= _clean_sign_approach(town, placement, "baseline").sign_margin_m <= 10.0


# ---- the fast path: regions of interest and two cameras at once ---------------------------------
WHOLE_FRAME = {"front_roi_px": [0, 0, 640, 480], "side_roi_px": [0, 0, 640, 480]}


def _sequential(loop: ClosedLoop) -> ClosedLoop:
    """Detect one camera after the other on this thread, as before the fast path."""
    loop.perception.detect_cameras = functools.partial(Perception.detect_cameras, loop.perception)
    return loop


def _stop_detections(loop: ClosedLoop, threshold: float) -> list[list[tuple]]:
    return [[(d.camera, d.confidence, d.box_xyxy_px) for d in r.detections if d.class_name == "stop_sign" and d.confidence >= threshold]
            for r in loop.records]


def test_two_cameras_at_once_detect_exactly_what_one_after_the_other_does():
    config = with_overrides(SimConfig(), {"policy": {"name": "side_camera"}, "perception": {"sensor_noise_std": 2.0}})
    loops = [ClosedLoop(config), _sequential(ClosedLoop(config))]
    try:
        for loop in loops:  # 45 m before the line at 20 m/s: both cameras see the sign
            loop.vehicle.place(loop.scene.stop_line_x_m - 45.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 20.0)
            for _ in range(30):
                loop.step()
        fast, slow = ([r.detections for r in loop.records] for loop in loops)
    finally:
        for loop in loops:
            loop.close()
    assert fast == slow
    assert any(d.camera == "side" and d.class_name == "stop_sign" for dets in fast for d in dets)


# Each town and each placement once with the clean sign, and each town under the attack. The whole grid (nine clean
# cells) passed in every run until 2026-11-26; it was cut to these to keep `make test` inside issue 25's 30 minutes.
# Each run starts at cruise speed 150 m out (CRUISE_START, tests/helpers.py), so both paths still compare every frame from
# before the first box to the stop, and a cell costs about half the study start's 40-50 CPU-s.
FAST_PATH_CELLS = ([("clean", "town07", "far"), ("clean", "town03", "near"), ("clean", "town10", "standard")]
                   + [("yang", town, "standard") for town in TOWNS.names()])


def test_the_fast_path_cells_cover_every_town_and_placement():
    clean = [(town, placement) for sign, town, placement in FAST_PATH_CELLS if sign == "clean"]
    assert {t for t, _ in clean} == set(TOWNS.names()) and {p for _, p in clean} == set(PLACEMENTS.names())


@pytest.mark.slow
@pytest.mark.parametrize("sign,town,placement", FAST_PATH_CELLS)
def test_fast_path_stops_where_the_whole_frame_one_camera_at_a_time_path_stops(sign, town, placement):
    # Before: every camera searched whole, one after the other. After: the default regions
    # of interest, two cameras at once. `combined` uses both cameras and the box height.
    overrides = {"scenario": {"town": town, "placement": placement, "sign": sign, **CRUISE_START}, "policy": {"name": "combined"},
                 "perception": {"sensor_noise_std": 2.0}}
    fast = ClosedLoop(with_overrides(SimConfig(), overrides))
    before = _sequential(ClosedLoop(with_overrides(SimConfig(), {**overrides, "perception": {"sensor_noise_std": 2.0, **WHOLE_FRAME}})))
    try:
        results = [loop.run() for loop in (fast, before)]
    finally:
        fast.close()
        before.close()
    assert results[0].sign_margin_m == results[1].sign_margin_m and results[0].outcome == results[1].outcome
    assert [r.x_m for r in fast.records] == [r.x_m for r in before.records]
    threshold = fast.config.policy.conf_threshold
    stops = _stop_detections(fast, threshold)
    assert stops == _stop_detections(before, threshold)
    assert not stops[0] and any(stops)  # the run starts before the first box, and the sign is seen
