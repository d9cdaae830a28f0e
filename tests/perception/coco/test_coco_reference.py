"""The PyTorch port against the TF.js runtime itself, on 7 avsim renders (slow: runs Node).

`node_reference/reference.js` runs centernet.json/.bin with @tensorflow/tfjs-core,
-converter and -backend-cpu 4.22.0 (pinned by the committed package-lock.json, installed
with `npm ci` into the git-ignored node_modules/ on first use). It is run here, on the
renders this test makes, rather than against committed outputs: the renders and the
reference then always come from the same pixels, on any machine.

The renders: each of the seven reference views once, the three towns taken in turn
(`one_of_each_view`). The pure-JS back-end takes about 11.5 s of one core a render here, so all
21 renders of the shared set took about 240 s, the slow pass's longest test; the YOLO and
NanoDet references, whose runtimes are faster, keep all 21.

Inputs: the front-camera frames go in as 640x480 and are resized to 512x512 on each side
(tf.image.resizeBilinear in Node, `resize_bilinear_tf` here), as @vladmandic/human feeds
the graph; the side-camera frames go in as a native-resolution 512x480 window padded to
512x512, so the network is also checked on unresized pixels. Every detection safely
inside the top 100 (score above the 100th by 1e-3) must have a twin of the same class with
its box within 0.5 px and its score within 1e-3.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from avsim.perception.coco import fetch
from avsim.perception.coco.model import load_centernet
from avsim.perception.coco.ops import resize_bilinear_tf
from avsim.perception.coco.preprocess import image_tensor
from tests.perception.reference_renders import one_of_each_view, render_views

NODE_DIR = Path(__file__).parent / "node_reference"
TFJS_VERSION = "4.22.0"
BOX_TOL_PX = 0.5
SCORE_TOL = 1e-3
SIDE_WINDOW_X0 = 64  # a 512 px wide window of the side camera's 640 px


def _side_window(frame: np.ndarray) -> torch.Tensor:
    """(1, 3, 512, 512): a native 512x480 window of the frame, padded with black rows below."""
    window = image_tensor(frame)[..., :, SIDE_WINDOW_X0:SIDE_WINDOW_X0 + 512]
    return F.pad(window, (0, 0, 0, 512 - window.shape[-2]))


@pytest.fixture(scope="module")
def node_reference(tmp_path_factory) -> Path:
    """NODE_DIR with its pinned node_modules installed; fails (not skips) without node and npm. The COCO and
    NanoDet reference tests share it, so under pytest-xdist the install holds a lock of the session's."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.fail("the TF.js reference needs node and npm on the PATH (apt-get install nodejs npm)")
    installed = NODE_DIR / "node_modules" / "@tensorflow" / "tfjs-core" / "package.json"
    with (tmp_path_factory.getbasetemp().parent / "node-reference.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not installed.is_file() or json.loads(installed.read_text())["version"] != TFJS_VERSION:
            subprocess.run([npm, "ci", "--no-audit", "--no-fund"], cwd=NODE_DIR, check=True, capture_output=True,
                           timeout=600)
    return NODE_DIR


def _match(reference: np.ndarray, ours: np.ndarray) -> tuple[int, float, float]:
    """(rows compared, max box difference [px], max score difference) of the safely-ranked rows.

    Asserts that every such row of `reference` has a twin in `ours` (same class, closest box).
    """
    floor = reference[:, 4].min() + SCORE_TOL
    compared, box_diff, score_diff = 0, 0.0, 0.0
    for row in reference[reference[:, 4] > floor]:
        same_class = ours[ours[:, 5] == row[5]]
        assert len(same_class), f"class {int(row[5])} (score {row[4]:.4f}) is missing from the port"
        distances = np.abs(same_class[:, :4] - row[:4]).max(axis=1)
        twin = same_class[np.argmin(distances)]
        box_diff = max(box_diff, float(distances.min()))
        score_diff = max(score_diff, float(abs(twin[4] - row[4])))
        compared += 1
    return compared, box_diff, score_diff


@pytest.mark.slow
def test_port_matches_tfjs_runtime_on_7_renders(node_reference, tmp_path):
    torch.set_num_threads(1)
    model = load_centernet()
    json_path, bin_path = fetch.model_paths()
    frames = one_of_each_view(render_views())
    assert len(frames) == 7 and {name.split("/")[0] for name, _ in frames} == {"town03", "town07", "town10"}
    assert sum("/front/" in name for name, _ in frames) == 4
    inputs, ours = [], {}
    for i, (name, frame) in enumerate(frames):
        path = tmp_path / f"{i:02d}.f32"
        if "/front/" in name:  # 640x480, resized to 512x512 on both sides
            image_tensor(frame).permute(0, 2, 3, 1).numpy().astype("<f4").tofile(path)
            inputs.append({"path": str(path), "height": 480, "width": 640, "resize_to": 512})
            x = resize_bilinear_tf(image_tensor(frame), (512, 512))
        else:  # a native window, the same 512x512 tensor on both sides
            x = _side_window(frame)
            x.permute(0, 2, 3, 1).numpy().astype("<f4").tofile(path)
            inputs.append({"path": str(path), "height": 512, "width": 512})
        with torch.inference_mode():
            ours[str(path)] = model.detect(x.contiguous(memory_format=torch.channels_last))[0].numpy()
    job = tmp_path / "job.json"
    out = tmp_path / "reference.json"
    job.write_text(json.dumps({"model_json": str(json_path), "model_bin": str(bin_path), "inputs": inputs, "out": str(out)}))
    subprocess.run(["node", "reference.js", str(job)], cwd=node_reference, check=True, timeout=900,
                   env={**os.environ, "NODE_OPTIONS": ""}, capture_output=True)
    reference = json.loads(out.read_text())
    assert reference["versions"]["tfjs-core"] == TFJS_VERSION and reference["versions"]["backend"] == "cpu"
    worst_box, worst_score, total = 0.0, 0.0, 0
    for (name, _), result in zip(frames, reference["results"]):
        compared, box_diff, score_diff = _match(np.asarray(result["detections"], np.float32), ours[result["path"]])
        assert compared >= 50, f"{name}: only {compared} of 100 detections are ranked clearly enough to compare"
        assert box_diff <= BOX_TOL_PX and score_diff <= SCORE_TOL, f"{name}: box {box_diff:.4f} px, score {score_diff:.2e}"
        worst_box, worst_score, total = max(worst_box, box_diff), max(worst_score, score_diff), total + compared
    print(f"\nTF.js reference: {len(frames)} renders, {total} detections compared; "
          f"max box difference {worst_box:.5f} px, max score difference {worst_score:.2e}")
