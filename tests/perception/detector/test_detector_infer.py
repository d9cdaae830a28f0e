"""The runner: Detection records in image pixels, batch == single, and latency-relevant setup."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest
import torch

from avsim.config import PerceptionConfig
from avsim.perception.base import Detection
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.perception.detector.letterbox import fit
from avsim.perception.detector.model import build_detector
from avsim.perception.detector.weights import SHIPPED_WEIGHTS, save_checkpoint
from avsim.perception.factory import build_frame_detector


@pytest.fixture(scope="module")
def weights_320(tmp_path_factory):
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        model = build_detector(width_mult=0.5)
    meta = {"arch": {"width_mult": 0.5, "depth": 1, "num_classes": 3, "act": "leaky_relu"}, "input_size": [320, 256],
            "class_names": ["stop_sign", "yield", "speed_limit"]}
    return save_checkpoint(tmp_path_factory.mktemp("w") / "w.pt", model, None, 0, meta)


class _OneBox(torch.nn.Module):
    """Stands in for the network: one confident stop-sign cell on the stride-8 map."""

    strides = (8, 16)

    def forward(self, x):
        b, _, h, w = x.shape
        outs = [torch.full((b, 8, h // s, w // s), -12.0) for s in self.strides]
        outs[0][:, 0, 10, 20] = 5.0
        outs[0][:, 1, 10, 20] = 5.0
        outs[0][:, 4:, 10, 20] = torch.tensor([0.25, -0.5, math.log(3.0), math.log(4.0)])
        return outs


def test_boxes_come_back_in_image_pixels(weights_320):
    runner = SignDetectorRunner(weights_320)
    assert torch.get_num_threads() <= 2
    runner.model = _OneBox()
    image = np.zeros((480, 640, 3), np.uint8)
    detections = runner.detect(image, "front", conf_threshold=0.5)
    assert len(detections) == 1
    det = detections[0]
    assert isinstance(det, Detection) and det.class_name == "stop_sign" and det.camera == "front"
    assert det.confidence == pytest.approx(1 / (1 + math.exp(-5.0)) ** 2, rel=1e-5)
    # input box: centre (20.5 * 8 + 2, 10.5 * 8 - 4) = (166, 80), 24 x 32 px; letterbox scale 0.5, pad_y 8
    box = fit(640, 480, (320, 256))
    expected = box.to_image(np.array([[154.0, 64.0, 178.0, 96.0]]))[0]
    np.testing.assert_allclose(det.box_xyxy_px, expected, atol=1e-3)
    assert det.height_px == pytest.approx(64.0, abs=1e-3) and not det.truncated


def test_detect_batch_matches_detect(weights_320, synthetic_dataset):
    runner = SignDetectorRunner(weights_320, conf_threshold=0.0)
    lines = [json.loads(line) for line in (synthetic_dataset / "val.jsonl").read_text().splitlines()[:3]]
    images = [cv2.cvtColor(cv2.imread(str(synthetic_dataset / line["image"])), cv2.COLOR_BGR2RGB) for line in lines]
    batched = runner.detect_batch(images, "side", conf_threshold=0.005)
    for image, dets in zip(images, batched):
        single = runner.detect(image, "side", conf_threshold=0.005)
        assert len(single) == len(dets)
        for a, b in zip(single, dets):
            assert a.class_name == b.class_name and a.camera == "side"
            assert a.confidence == pytest.approx(b.confidence, abs=1e-4)
            np.testing.assert_allclose(a.box_xyxy_px, b.box_xyxy_px, atol=1e-2)
        assert all(0 <= d.box_xyxy_px[0] <= d.box_xyxy_px[2] <= 640 and 0 <= d.box_xyxy_px[1] <= d.box_xyxy_px[3] <= 480 for d in dets)
        assert [d.confidence for d in dets] == sorted((d.confidence for d in dets), reverse=True)
    assert runner.detect_batch([], "front") == []


def test_the_default_config_runs_bf16_where_the_cpu_has_it_and_fp32_elsewhere(monkeypatch):
    assert PerceptionConfig().detector_precision == "auto"
    for supported, arithmetic in ((True, "bf16"), (False, "fp32")):
        monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda supported=supported: supported)
        assert build_frame_detector(PerceptionConfig(kind="detector")).precision == arithmetic


@pytest.mark.skipif(not torch.ops.mkldnn._is_mkldnn_bf16_supported(), reason="this CPU has no oneDNN bf16 kernels")
def test_the_bf16_copy_computes_what_autocast_computes_bit_for_bit(synthetic_dataset):
    """The runner's bf16 network is a bf16 copy of the fused float32 one; it must give the maps that bfloat16
    autocast on the float32 network gives, bit for bit, on the shipped weights and a real front crop."""
    runner = SignDetectorRunner(SHIPPED_WEIGHTS, precision="bf16")
    line = json.loads((synthetic_dataset / "val.jsonl").read_text().splitlines()[0])
    image = cv2.cvtColor(cv2.imread(str(synthetic_dataset / line["image"])), cv2.COLOR_BGR2RGB)
    batch = torch.from_numpy(np.stack([image[32:416, 64:544], image[64:448, 160:640]])).permute(0, 3, 1, 2)
    batch = batch.float().div(255.0).contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        copied = runner._maps(batch)
        with torch.autocast("cpu", dtype=torch.bfloat16):
            autocast = runner.model(batch)
    assert [m.dtype for m in copied] == [torch.bfloat16] * len(autocast)
    for ours, theirs in zip(copied, autocast):
        assert torch.equal(ours, theirs)
