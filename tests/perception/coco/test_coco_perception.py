"""`--perception coco` in the closed loop and through `avsim detect`, on fresh renders."""

import json

import cv2
import numpy as np
import pytest

from avsim import cli
from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.base import Perception
from avsim.perception.coco.labels import AVSIM_CLASS_NAMES
from avsim.perception.factory import build_perception
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import TOWNS

THRESHOLD = SimConfig().policy.conf_threshold


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _truth_and_found(loop: ClosedLoop, dist_m: float, camera: str = "front"):
    loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    oracle = build_perception(PerceptionConfig(kind="oracle", min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
    truth = [d for d in oracle.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
    found = [d for d in loop.perception.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
    return truth, found


@pytest.mark.parametrize("town", TOWNS.names())
def test_coco_finds_the_clean_stop_sign_at_10_to_20_m_in_every_town(town):
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}, "perception": {"kind": "coco"}}))
    try:
        assert isinstance(loop.perception, Perception) and loop.perception.name == "coco"
        for dist_m in (10.0, 15.0, 20.0):
            truth, found = _truth_and_found(loop, dist_m)
            assert len(truth) == 1
            on_sign = [d for d in found if _iou(d.box_xyxy_px, truth[0].box_xyxy_px) >= 0.5]
            assert on_sign, f"{town} {dist_m} m: no stop_sign box on the sign (found {[round(d.confidence, 2) for d in found]})"
            assert on_sign[0].confidence >= THRESHOLD, f"{town} {dist_m} m: the sign scores {on_sign[0].confidence:.2f}"
    finally:
        loop.close()


def test_other_coco_classes_are_reported_under_their_coco_names():
    assert AVSIM_CLASS_NAMES[11] == "stop_sign" and "stop sign" not in AVSIM_CLASS_NAMES
    assert AVSIM_CLASS_NAMES[0] == "person" and AVSIM_CLASS_NAMES[9] == "traffic light"


def test_sensor_noise_is_seeded_and_changes_the_scores():
    def scores(noise_std: float, seed: int) -> list[float]:
        config = with_overrides(SimConfig(), {"scenario": {"seed": seed},
                                              "perception": {"kind": "coco", "sensor_noise_std": noise_std}})
        loop = ClosedLoop(config)
        try:
            return [d.confidence for d in _truth_and_found(loop, 20.0)[1]]
        finally:
            loop.close()

    noisy = scores(4.0, 0)
    assert scores(4.0, 0) == noisy  # same seed, same noise, same scores
    assert noisy != scores(0.0, 0) and scores(4.0, 1) != noisy


def test_avsim_detect_on_a_rendered_frame_finds_the_sign_within_3_px(tmp_path, capsys):
    loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": "oracle", "min_box_height_px": 1.0}}))
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - 20.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        frame = loop.rig.render_rgb(loop.data, "front")
        truth = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
    finally:
        loop.close()
    path = tmp_path / "frame.png"
    cv2.imwrite(str(path), np.ascontiguousarray(frame[..., ::-1]))
    assert len(truth) == 1
    for perception in ("coco", "detector"):
        assert cli.main(["detect", "--perception", perception, str(path)]) == 0
        record = json.loads(capsys.readouterr().out.splitlines()[0])
        assert (record["image"], record["width"], record["height"], record["perception"]) == (str(path), 640, 480, perception)
        stops = [d for d in record["detections"] if d["class"] == "stop_sign"]
        assert stops and stops[0]["confidence"] >= THRESHOLD, (perception, record["detections"][:3])
        error_px = max(abs(a - b) for a, b in zip(stops[0]["box_xyxy_px"], truth[0].box_xyxy_px))
        assert error_px <= 3.0, f"{perception}: box {stops[0]['box_xyxy_px']} is {error_px:.1f} px from {truth[0].box_xyxy_px}"


@pytest.mark.parametrize("mode", ["resize", "crop", "upscale"])
def test_avsim_detect_maps_boxes_back_on_images_of_any_size(tmp_path, capsys, mode):
    """A frame stretched to 900x500 (another size and aspect): the sign's box lands on the stretched sign."""
    loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": "oracle", "min_box_height_px": 1.0}}))
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - 12.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        frame = loop.rig.render_rgb(loop.data, "front")
        truth = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"][0]
    finally:
        loop.close()
    sx, sy = 900 / 640, 500 / 480
    path = tmp_path / "photo.jpg"
    cv2.imwrite(str(path), cv2.resize(np.ascontiguousarray(frame[..., ::-1]), (900, 500), interpolation=cv2.INTER_LINEAR))
    assert cli.main(["detect", "--perception", "coco", "--set", f"perception.coco_input={mode}", str(path)]) == 0
    record = json.loads(capsys.readouterr().out)
    assert (record["width"], record["height"]) == (900, 500)
    x0, y0, x1, y1 = truth.box_xyxy_px
    stretched = (x0 * sx, y0 * sy, x1 * sx, y1 * sy)
    on_sign = [d for d in record["detections"] if d["class"] == "stop_sign" and _iou(d["box_xyxy_px"], stretched) >= 0.5]
    assert on_sign, f"{mode}: no stop_sign box on the sign at {stretched}: {record['detections'][:3]}"


@pytest.mark.parametrize("args,message", [
    (["--perception", "oracle"], "oracle perception reads ground truth"),
    (["--perception", "coco", "--set", "perception.coco_input=zoom"], "perception.coco_input must be one of"),
    (["--perception", "coco", "MISSING"], "does not exist"),
])
def test_avsim_detect_refuses_bad_input_in_one_line(tmp_path, capsys, args, message):
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), np.zeros((48, 64, 3), np.uint8))
    argv = ["detect", *[str(tmp_path / "nope.png") if a == "MISSING" else a for a in args]]
    if "MISSING" not in args:
        argv.append(str(image))
    code = cli.main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2 and len(lines) == 1 and message in lines[0], captured.err
    assert captured.out == ""


def test_two_cameras_at_once_give_the_same_detections_as_one_after_the_other():
    config = with_overrides(SimConfig(), {"perception": {"kind": "coco", "sensor_noise_std": 2.0}})
    results = []
    for together in (True, False):
        loop = ClosedLoop(config)
        try:
            loop.vehicle.place(loop.scene.stop_line_x_m - 18.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            if together:
                results.append(loop.perception.detect_cameras(loop.rig, loop.data, ("front", "side")))
            else:
                results.append({camera: loop.perception.detect(loop.rig, loop.data, camera) for camera in ("front", "side")})
        finally:
            loop.close()
    assert results[0] == results[1] and results[0]["front"] and results[0]["side"]
