"""`--perception onnx`: a user's YOLO-layout model in the loop; malformed files are one line, exit 2."""

import numpy as np
import pytest
import torch

from avsim import cli
from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.onnx.infer import OnnxModelError, OnnxRunner
from avsim.vehicle.physics import FRONT_BUMPER_X_M

CLASSES = "['stop_sign', 'yield', 'speed_limit']"


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("onnx") / "sign_detector.onnx"
    assert cli.main(["detector", "export", "--format", "onnx", "--out", str(out)]) == 0
    return str(out)


def _overrides(path: str, classes: str = CLASSES) -> list[str]:
    return ["--set", f"perception.onnx_path='{path}'", "--set", f"perception.onnx_classes={classes}"]


def test_onnx_perception_sees_the_stop_sign_in_the_closed_loop(exported):
    config = with_overrides(SimConfig(), {"perception": {"kind": "onnx", "onnx_path": exported,
                                                         "onnx_classes": list(SIGN_CLASSES)}})
    loop = ClosedLoop(config)
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - 25.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        detections = loop.perception.detect_cameras(loop.rig, loop.data, ("front", "side"))
    finally:
        loop.close()
    assert detections["front"] and detections["front"][0].class_name == "stop_sign"
    assert detections["front"][0].confidence >= 0.5


@pytest.mark.parametrize("content", [b"", b"not an onnx file", b"\x08\x07\x12\x04junk"], ids=["empty", "text", "torn"])
@pytest.mark.parametrize("command", ["run", "detect"])
def test_malformed_onnx_is_one_line_and_exit_2(tmp_path, capsys, content, command):
    model = tmp_path / "bad.onnx"
    model.write_bytes(content)
    image = tmp_path / "frame.png"
    import cv2

    cv2.imwrite(str(image), np.zeros((48, 64, 3), np.uint8))
    out = tmp_path / "out.json"
    argv = (["run", "--perception", "onnx", *_overrides(str(model)), "--json", str(out)] if command == "run"
            else ["detect", "--perception", "onnx", *_overrides(str(model)), str(image)])
    code = cli.main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2 and len(lines) == 1, captured.err
    assert "bad.onnx" in lines[0] and "cannot be loaded" in lines[0]
    assert not out.exists() and captured.out == ""


def test_a_folder_for_the_model_is_named_as_one(tmp_path, capsys):
    code = cli.main(["run", "--perception", "onnx", *_overrides(str(tmp_path)), "--json", str(tmp_path / "out.json")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and f"ONNX model {tmp_path} is a folder" in err, err
    assert not (tmp_path / "out.json").exists()


def test_a_class_list_that_does_not_fit_the_output_is_refused(exported, capsys):
    code = cli.main(["run", "--perception", "onnx", *_overrides(exported, "['stop_sign']")])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1
    assert "expected [1, 4 + C, N] with C = 1" in lines[0]


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # torch's TorchScript exporter, as `detector export` uses
def test_a_model_that_is_not_an_image_detector_is_refused(tmp_path):
    path = tmp_path / "linear.onnx"
    torch.onnx.export(torch.nn.Linear(4, 7), (torch.zeros(1, 4),), str(path), dynamo=False, input_names=["x"])
    with pytest.raises(OnnxModelError, match=r"must take one \(1, 3, H, W\) image"):
        OnnxRunner(path, tuple(SIGN_CLASSES), 0.1)


def test_onnx_needs_its_path_and_classes(capsys):
    code = cli.main(["run", "--perception", "onnx"])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1 and "perception.onnx_path" in lines[0]
