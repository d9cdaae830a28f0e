"""`avsim detector export --format onnx`: the YOLO-layout file gives the PyTorch detector's detections."""

import numpy as np
import pytest

from avsim import cli
from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.perception.detector.weights import SHIPPED_WEIGHTS
from avsim.perception.onnx.infer import OnnxRunner
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import TOWNS

TOLERANCE = 1e-4


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("onnx") / "sign_detector.onnx"
    assert cli.main(["detector", "export", "--format", "onnx", "--out", str(out)]) == 0
    return str(out)


def _renders() -> list[tuple[str, np.ndarray]]:
    frames = []
    for town in TOWNS.names():
        loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}, "perception": {"kind": "oracle"}}))
        try:
            for camera, dist_m in (("front", 15.0), ("front", 35.0), ("side", 10.0)):
                loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
                frames.append((camera, loop.rig.render_rgb(loop.data, camera)))
        finally:
            loop.close()
    return frames


def test_the_export_has_the_yolo_layout(exported):
    runner = OnnxRunner(exported, SIGN_CLASSES, 0.1)
    inputs, outputs = runner.session.get_inputs(), runner.session.get_outputs()
    assert inputs[0].shape == [1, 3, 480, 640]
    assert outputs[0].shape == [1, 4 + len(SIGN_CLASSES), 60 * 80 + 30 * 40]  # cells at strides 8 and 16
    assert runner.input_size == (640, 480)


def test_onnx_detections_match_pytorch_on_real_renders(exported):
    onnx_runner = OnnxRunner(exported, SIGN_CLASSES, 0.1)
    torch_runner = SignDetectorRunner(SHIPPED_WEIGHTS, conf_threshold=0.1, num_threads=1)
    compared = 0
    for camera, frame in _renders():
        expected, got = torch_runner.detect(frame, camera), onnx_runner.detect(frame, camera)
        assert [d.class_name for d in got] == [d.class_name for d in expected]
        for a, b in zip(got, expected):
            assert abs(a.confidence - b.confidence) <= TOLERANCE
            assert max(abs(u - v) for u, v in zip(a.box_xyxy_px, b.box_xyxy_px)) <= TOLERANCE * max(1.0, max(b.box_xyxy_px))
            assert a.truncated == b.truncated
            compared += 1
    assert compared >= 9  # every render holds at least the stop sign
