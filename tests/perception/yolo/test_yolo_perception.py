"""`--perception yolo` in the closed loop and through `avsim detect`, on fresh renders."""

import json
import shutil

import cv2
import numpy as np
import pytest

from avsim import cli
from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.ap import box_iou
from avsim.perception.factory import build_frame_detector, build_perception
from avsim.perception.yolo import fetch
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import TOWNS
from avsim.sensors.regions import STUDY_REGIONS_PX
from helpers import needs_bf16

THRESHOLD = SimConfig().policy.conf_threshold


def _iou(a, b) -> float:
    return float(box_iou(np.asarray([a], float), np.asarray([b], float))[0, 0])


def _centred_on(box, truth) -> bool:
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    return truth[0] <= cx <= truth[2] and truth[1] <= cy <= truth[3]


def _frame_and_truth(dist_m: float, town: str = "town07", camera: str = "front"):
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town},
                                                   "perception": {"kind": "oracle", "min_box_height_px": 1.0}}))
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        truth = [d for d in loop.perception.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
        return loop.rig.render_rgb(loop.data, camera), truth
    finally:
        loop.close()


@pytest.mark.parametrize("town", TOWNS.names())
def test_yolo_finds_the_clean_stop_sign_at_10_to_20_m_in_every_town(town):
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}, "perception": {"kind": "yolo"}}))
    oracle = build_perception(PerceptionConfig(kind="oracle", min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
    try:
        assert loop.perception.name == "yolo"
        for dist_m in (10.0, 15.0, 20.0):
            loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            truth = [d for d in oracle.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
            found = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
            assert len(truth) == 1
            on_sign = [d for d in found if _iou(d.box_xyxy_px, truth[0].box_xyxy_px) >= 0.5]
            assert on_sign and on_sign[0].confidence >= THRESHOLD, f"{town} {dist_m} m: {found}"
    finally:
        loop.close()


@pytest.mark.parametrize("mode", ["resize", "crop", "upscale"])
def test_every_input_mode_finds_the_sign_at_10_m_and_reports_only_boxes_centred_in_the_region(mode):
    """On the sign: its box centred inside the sign's (YOLOv3-tiny often boxes only the legend, at any input)."""
    frame, truth = _frame_and_truth(10.0)
    config = PerceptionConfig(kind="yolo", yolo_input=mode)
    region = STUDY_REGIONS_PX["front"]
    found = build_frame_detector(config).detect(frame, "front", region_px=region)
    stops = [d for d in found if d.class_name == "stop_sign" and _centred_on(d.box_xyxy_px, truth[0].box_xyxy_px)]
    assert stops and stops[0].confidence >= THRESHOLD, found
    for d in found:
        cx, cy = (d.box_xyxy_px[0] + d.box_xyxy_px[2]) / 2, (d.box_xyxy_px[1] + d.box_xyxy_px[3]) / 2
        assert region[0] <= cx < region[2] and region[1] <= cy < region[3]
    assert [d.confidence for d in found] == sorted((d.confidence for d in found), reverse=True)


@needs_bf16
def test_bf16_finds_the_same_sign_with_a_close_score():
    frame, truth = _frame_and_truth(15.0)
    scores = {}
    for precision in ("fp32", "bf16"):
        found = build_frame_detector(PerceptionConfig(kind="yolo", yolo_precision=precision)).detect(
            frame, "front", region_px=STUDY_REGIONS_PX["front"])
        scores[precision] = max(d.confidence for d in found if d.class_name == "stop_sign"
                                and _iou(d.box_xyxy_px, truth[0].box_xyxy_px) >= 0.5)
    assert abs(scores["fp32"] - scores["bf16"]) <= 0.05, scores


def test_a_users_own_darknet_files_load_through_the_config(tmp_path):
    frame, _ = _frame_and_truth(12.0)
    cfg, weights, names = fetch.model_paths()
    for path in (cfg, weights, names):
        shutil.copy(path, tmp_path / f"mine{path.suffix}")
    own = PerceptionConfig(kind="yolo", yolo_cfg=str(tmp_path / "mine.cfg"), yolo_weights=str(tmp_path / "mine.weights"),
                           yolo_names=str(tmp_path / "mine.names"))
    region = STUDY_REGIONS_PX["front"]
    assert (build_frame_detector(own).detect(frame, "front", region_px=region)
            == build_frame_detector(PerceptionConfig(kind="yolo")).detect(frame, "front", region_px=region))


def test_avsim_detect_prints_a_box_inside_the_sign(tmp_path, capsys):
    frame, truth = _frame_and_truth(15.0)
    path = tmp_path / "frame.png"
    cv2.imwrite(str(path), np.ascontiguousarray(frame[..., ::-1]))
    assert cli.main(["detect", "--perception", "yolo", "--set", "perception.yolo_input=crop", str(path)]) == 0
    record = json.loads(capsys.readouterr().out)
    assert (record["width"], record["height"], record["perception"]) == (640, 480, "yolo")
    stops = [d for d in record["detections"] if d["class"] == "stop_sign"]
    x0, y0, x1, y1 = truth[0].box_xyxy_px
    assert stops[0]["confidence"] >= THRESHOLD and _centred_on(stops[0]["box_xyxy_px"], truth[0].box_xyxy_px), stops
    assert all(a <= b for a, b in zip([x0 - 1, y0 - 1, -x1 - 1, -y1 - 1],
                                      [v * s for v, s in zip(stops[0]["box_xyxy_px"], (1, 1, -1, -1))])), stops


@pytest.mark.parametrize("sets, message", [
    (["perception.yolo_input=zoom"], "perception.yolo_input must be one of"),
    (["perception.yolo_cfg=x.cfg"], "perception.yolo_cfg and perception.yolo_weights go together"),
    (["perception.yolo_cfg=MISSING.cfg", "perception.yolo_weights=MISSING.weights"], "MISSING.cfg does not exist"),
    (["perception.yolo_cfg=TINY", "perception.yolo_weights=FETCHED"], "the weights are not for this cfg"),
])
def test_bad_yolo_settings_are_one_line_errors(tmp_path, capsys, sets, message):
    from tests.perception.yolo.darknet_files import TINY_CFG

    (tmp_path / "tiny.cfg").write_text(TINY_CFG.replace("classes=2", "classes=80").replace("filters=21", "filters=255")
                                       .replace("filters=14", "filters=170"))
    replace = {"TINY": str(tmp_path / "tiny.cfg"), "FETCHED": str(fetch.model_paths()[1])}
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), np.zeros((48, 64, 3), np.uint8))
    argv = ["detect", "--perception", "yolo", str(image)]
    for item in sets:
        key, value = item.split("=")
        argv += ["--set", f"{key}={replace.get(value, value)}"]
    code = cli.main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2 and len(lines) == 1 and message in lines[0], captured.err
    assert captured.out == ""


@pytest.mark.parametrize("damage", ["missing", "altered"])
def test_yolo_without_good_fetched_files_is_one_line_naming_the_fetch_command(tmp_path, monkeypatch, capsys, damage):
    cache = tmp_path / "cache"
    shutil.copytree(fetch.CACHE_DIR, cache)
    if damage == "missing":
        (cache / "yolov3-tiny.weights").unlink()
    else:
        (cache / "yolov3-tiny.cfg").write_text((cache / "yolov3-tiny.cfg").read_text().replace("filters=16", "filters=17"))
    monkeypatch.setattr(fetch, "CACHE_DIR", cache)
    out = tmp_path / "out.json"
    code = cli.main(["run", "--perception", "yolo", "--json", str(out)])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert "python -m avsim.perception.yolo.fetch" in lines[0] and ("missing" if damage == "missing" else "sha256") in lines[0]
    assert not out.exists()


def test_a_closed_loop_step_is_deterministic_with_noise():
    config = with_overrides(SimConfig(), {"scenario": {"seed": 3}, "perception": {"kind": "yolo", "sensor_noise_std": 2.0}})
    results = []
    for _ in range(2):
        loop = ClosedLoop(config)
        try:
            loop.vehicle.place(loop.scene.stop_line_x_m - 18.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            results.append(loop.perception.detect_cameras(loop.rig, loop.data, ("front", "side")))
        finally:
            loop.close()
    assert results[0] == results[1] and results[0]["front"]


def test_a_three_network_ensemble_with_two_votes_fuses_yolo_with_the_others():
    frame, truth = _frame_and_truth(12.0)
    config = PerceptionConfig(kind="ensemble", ensemble_members=("detector", "coco", "yolo"), ensemble_fusion="k_of_n",
                              ensemble_k=2)
    found = build_frame_detector(config).detect(frame, "front", region_px=STUDY_REGIONS_PX["front"])
    stops = [d for d in found if d.class_name == "stop_sign"]
    assert stops and stops[0].confidence >= THRESHOLD and _centred_on(stops[0].box_xyxy_px, truth[0].box_xyxy_px)
    assert stops[0].source.count("+") >= 1 and "yolo" in {m for d in stops for m in d.source.split("+")}
