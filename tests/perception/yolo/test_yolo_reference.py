"""The PyTorch Darknet reader against OpenCV 4's Darknet importer, on 21 avsim renders (slow).

`opencv_reference/reference.py` runs `cv2.dnn.readNetFromDarknet` on the fetched
yolov3-tiny.cfg/.weights in a side virtual environment (`opencv_reference/.venv`, git-ignored,
made on first use from the pinned `requirements.txt`: opencv-python-headless 4.14.0.94, numpy
2.4.6), because avsim's own OpenCV 5 has no Darknet importer. Both sides get the same input
tensors, made here from renders of this run (3 towns, both cameras, 6-40 m; see
`tests/perception/reference_renders.py`) in two of `--perception yolo`'s input modes: front
frames as the default `upscale` x2 of the front region of interest (704 x 512), side frames
`resize`d whole to the cfg's 416 x 416. Every one of the heads' rows is compared, row for row:
- the box (centre and size) within 0.5 px;
- objectness within 1e-3;
- objectness x class probability within 1e-3 for every class OpenCV reports (it zeroes
  scores at or below its threshold; ours must then lie at or below it too, within 1e-3).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from avsim.config import PerceptionConfig
from avsim.perception.coco.preprocess import image_tensor
from avsim.perception.yolo import fetch
from avsim.perception.yolo.model import PIXEL_SCALE, load_yolo
from avsim.perception.yolo.preprocess import network_input
from avsim.sensors.regions import STUDY_REGIONS_PX
from tests.perception.reference_renders import render_views

REFERENCE_DIR = Path(__file__).parent / "opencv_reference"
SIDE_VENV = REFERENCE_DIR / ".venv"
OPENCV_VERSION = "4.14.0"
BOX_TOL_PX = 0.5
SCORE_TOL = 1e-3
STOP_SIGN = 11


@pytest.fixture(scope="module")
def side_python() -> Path:
    """The side environment's python, with the pinned OpenCV 4 installed (made on first use)."""
    python = SIDE_VENV / "bin" / "python"
    check = [str(python), "-c", "import cv2, numpy; print(cv2.__version__, numpy.__version__)"]
    pinned = dict(line.split("==") for line in (REFERENCE_DIR / "requirements.txt").read_text().splitlines()
                  if "==" in line and not line.startswith("#"))
    wanted = f"{OPENCV_VERSION} {pinned['numpy']}"
    if not python.exists() or subprocess.run(check, capture_output=True, text=True).stdout.strip() != wanted:
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(SIDE_VENV)], check=True, capture_output=True, timeout=300)
        subprocess.run([str(python), "-m", "pip", "install", "--quiet", "-r", str(REFERENCE_DIR / "requirements.txt")],
                       check=True, capture_output=True, timeout=900)
    assert subprocess.run(check, capture_output=True, text=True, check=True).stdout.strip() == wanted
    return python


def _as_cxcywh(boxes_xyxy: np.ndarray) -> np.ndarray:
    return np.concatenate([(boxes_xyxy[:, :2] + boxes_xyxy[:, 2:]) / 2, boxes_xyxy[:, 2:] - boxes_xyxy[:, :2]], axis=1)


@pytest.mark.slow
def test_reader_matches_opencv_darknet_importer_on_21_renders(side_python, tmp_path):
    torch.set_num_threads(1)
    model = load_yolo()
    cfg_path, weights_path, _ = fetch.model_paths()
    frames = render_views()
    assert len(frames) >= 20 and {name.split("/")[2] for name, _ in frames} == {"front", "side"}
    front_roi = STUDY_REGIONS_PX["front"]
    inputs, ours = [], []
    for i, (name, frame) in enumerate(frames):
        if "/front/" in name:
            x, _ = network_input(image_tensor(frame), "upscale", model.input_size_px, 32, front_roi, 2.0)
        else:
            x, _ = network_input(image_tensor(frame), "resize", model.input_size_px, 32)
        path = tmp_path / f"{i:02d}.npy"
        np.save(path, np.ascontiguousarray((x * PIXEL_SCALE).numpy(), dtype=np.float32))  # what the network sees
        inputs.append(str(path))
        with torch.inference_mode():  # the input as deployed (channels-last), scaled as the model scales it
            decoded = model.decoded(x)
        ours.append((x.shape[-1], x.shape[-2], decoded))
    job, out = tmp_path / "job.json", tmp_path / "outputs.json"
    job.write_text(json.dumps({"cfg": str(cfg_path), "weights": str(weights_path), "inputs": inputs, "out": str(out)}))
    subprocess.run([str(side_python), str(REFERENCE_DIR / "reference.py"), str(job)], check=True, timeout=900,
                   capture_output=True)
    reference = json.loads(out.read_text())
    assert reference["versions"]["opencv"] == OPENCV_VERSION
    worst_box, worst_obj, worst_score, compared, stop_scores, thresholds = 0.0, 0.0, 0.0, 0, [], []
    for (name, _), (width, height, decoded), ref_path in zip(frames, ours, reference["outputs"]):
        ref = np.load(ref_path).astype(np.float64)
        assert ref.shape == (decoded.boxes_xyxy.shape[1], 85), name
        box_px = np.abs(_as_cxcywh(decoded.boxes_xyxy[0].double().numpy()) - ref[:, :4] * [width, height, width, height])
        obj = np.abs(decoded.objectness[0].double().numpy() - ref[:, 4])
        scores, ref_scores = decoded.class_scores()[0].double().numpy(), ref[:, 5:]
        reported = ref_scores > 0
        threshold = ref_scores[reported].min() if reported.any() else 1.0
        score = np.abs(scores - ref_scores)[reported]
        assert box_px.max() <= BOX_TOL_PX, f"{name}: box off by {box_px.max():.4f} px"
        assert obj.max() <= SCORE_TOL, f"{name}: objectness off by {obj.max():.2e}"
        assert score.size == 0 or score.max() <= SCORE_TOL, f"{name}: score off by {score.max():.2e}"
        assert (scores[~reported] <= threshold + SCORE_TOL).all(), f"{name}: a score OpenCV zeroes is above its threshold"
        worst_box, worst_obj = max(worst_box, box_px.max()), max(worst_obj, obj.max())
        worst_score = max(worst_score, score.max() if score.size else 0.0)
        compared += int(reported.sum())
        thresholds.append(threshold)
        stop_scores.append(ref_scores[:, STOP_SIGN].max())
    assert sum(s > 0.5 for s in stop_scores) >= 10, f"too few renders with a confident stop sign to compare: {stop_scores}"
    print(f"\nOpenCV {OPENCV_VERSION} Darknet importer: {len(frames)} renders, {sum(len(np.load(p)) for p in reference['outputs'])} "
          f"rows, {compared} class scores compared; max box difference {worst_box:.5f} px, objectness {worst_obj:.2e}, "
          f"score {worst_score:.2e}; smallest score OpenCV reports {min(thresholds):.4f}")
