"""`perception.coco_precision = "bf16"`: deterministic, near the float32 port on real renders, and
leaving the float32 port (the reference-checked, differentiable one) untouched. The tests that run bf16
need a CPU with oneDNN's bf16 kernels; building the copy, and choosing it, are checked on any CPU."""

import numpy as np
import pytest
import torch

from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.perception.ap import box_iou
from avsim.perception.coco.bf16 import FLOAT32_LAYERS, Bf16CenterNet, Float32Island
from avsim.perception.coco.model import load_centernet
from avsim.perception.coco.network import HEATMAP_NAME
from avsim.perception.coco.infer import CocoRunner
from avsim.perception.factory import build_frame_detector
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.sensors.regions import STUDY_REGIONS_PX
from helpers import needs_bf16

# The largest deviations of bf16 from fp32 measured on 3000 make-data frames (docs/perception.md, "COCO CenterNet";
# `python -m avsim.perception.coco.realism --modes upscale --precisions fp32,bf16`), between each fp32
# stop-sign detection and its bf16 twin: on the labelled sign, score 0.057 and box edge 0.38 px; on
# every other stop-sign detection (trees, mostly), score 0.144.
SIGN_SCORE_TOL = 0.06
SIGN_EDGE_TOL_PX = 0.4
OTHER_SCORE_TOL = 0.15


@pytest.fixture(scope="module")
def fp32_model():
    torch.set_num_threads(1)
    return load_centernet()


@pytest.fixture
def with_bf16(monkeypatch):
    """The CPU check says yes: the bf16 copy can be built (not run fast) on any CPU."""
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: True)


@pytest.fixture(scope="module")
def models(fp32_model):
    return fp32_model, Bf16CenterNet(fp32_model)


@pytest.fixture(scope="module")
def renders():
    """(name, camera, frame, the sign's box from segmentation) for the front camera 15, 25 and 35 m
    before the stop line and the side camera at 8 m, in each town."""
    frames = []
    for town in ("town03", "town07", "town10"):
        loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town},
                                                       "perception": {"kind": "oracle", "min_box_height_px": 1.0}}))
        try:
            for camera, dist_m in (("front", 15.0), ("front", 25.0), ("front", 35.0), ("side", 8.0)):
                loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
                truth = [d.box_xyxy_px for d in loop.perception.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
                frames.append((f"{town} {camera} {dist_m:g} m", camera, loop.rig.render_rgb(loop.data, camera), truth[0]))
        finally:
            loop.close()
    return frames


def _stop_signs(runner: CocoRunner, frame: np.ndarray, camera: str) -> np.ndarray:
    """(n, 5): score, x0, y0, x1, y1 of the stop signs found in the camera's default region."""
    defaults = PerceptionConfig()
    region = STUDY_REGIONS_PX[camera]
    found = [d for d in runner.detect(frame, camera, region_px=region) if d.class_name == "stop_sign"]
    return np.array([[d.confidence, *d.box_xyxy_px] for d in found]).reshape(-1, 5)


@needs_bf16
def test_bf16_stays_within_the_measured_deviation_of_fp32_on_real_renders(models, renders):
    fp32, bf16 = (CocoRunner(model, "upscale", 2.0, 0.1) for model in models)
    signs = 0
    for name, camera, frame, truth in renders:
        reference, ours = _stop_signs(fp32, frame, camera), _stop_signs(bf16, frame, camera)
        for row in reference[reference[:, 0] >= 0.3]:  # clear detections: each must have its twin
            iou = box_iou(row[None, 1:], ours[:, 1:])[0] if len(ours) else np.zeros(0)
            assert len(iou) and iou.max() >= 0.5, f"{name}: the fp32 stop sign {row.round(2)} has no bf16 twin"
            twin = ours[iou.argmax()]
            on_sign = box_iou(row[None, 1:], np.asarray([truth]))[0, 0] >= 0.5
            assert abs(twin[0] - row[0]) <= (SIGN_SCORE_TOL if on_sign else OTHER_SCORE_TOL), \
                f"{name}: score {row[0]:.4f} (fp32) against {twin[0]:.4f} (bf16), {'on' if on_sign else 'off'} the sign"
            if on_sign:
                assert np.abs(twin[1:] - row[1:]).max() <= SIGN_EDGE_TOL_PX, f"{name}: box {row[1:].round(2)} against {twin[1:].round(2)}"
                signs += 1
    assert signs >= 9  # the sign, in most of the 12 frames


@needs_bf16
def test_bf16_is_deterministic(models, renders):
    _, bf16 = models
    runner = CocoRunner(bf16, "upscale", 2.0, 0.1)
    rebuilt = CocoRunner(Bf16CenterNet(load_centernet()), "upscale", 2.0, 0.1)
    for name, camera, frame, _ in renders[:4]:
        first = runner.detect(frame, camera, region_px=(288, 0, 640, 256))
        assert first == runner.detect(frame, camera, region_px=(288, 0, 640, 256)), name
        assert first == rebuilt.detect(frame, camera, region_px=(288, 0, 640, 256)), name


def test_building_bf16_leaves_the_float32_port_as_it_was(fp32_model, with_bf16):
    fp32, bf16 = fp32_model, Bf16CenterNet(fp32_model)
    assert all(p.dtype == torch.float32 for p in fp32.parameters())
    assert fp32.network.nodes[fp32.network.producer_index(HEATMAP_NAME)].activation == "Sigmoid"
    assert bf16.network.nodes[bf16.network.producer_index(HEATMAP_NAME)].activation is None  # it decodes logits
    islands = [bf16.network.nodes[bf16.network.producer_index(name)] for name in FLOAT32_LAYERS]
    assert all(isinstance(island, Float32Island) for island in islands)
    kept = {id(p) for island in islands for p in island.parameters()}
    assert kept and all(p.dtype == torch.float32 for island in islands for p in island.parameters())
    assert all(p.dtype == torch.bfloat16 for p in bf16.parameters() if id(p) not in kept)


@pytest.mark.parametrize("cpu_runs_bf16", [True, False])
def test_the_config_chooses_the_precision_and_auto_follows_the_cpu(monkeypatch, cpu_runs_bf16):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: cpu_runs_bf16)
    built = {precision: isinstance(build_frame_detector(PerceptionConfig(kind="coco", coco_precision=precision)).model,
                                   Bf16CenterNet) for precision in ("auto", "fp32")}
    assert built == {"auto": cpu_runs_bf16, "fp32": False}
    assert PerceptionConfig().coco_precision == "auto"  # the default runs on every CPU
    if cpu_runs_bf16:
        assert isinstance(build_frame_detector(PerceptionConfig(kind="coco", coco_precision="bf16")).model, Bf16CenterNet)


def test_a_cpu_without_bf16_is_told_to_use_auto_or_fp32(fp32_model, monkeypatch):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: False)
    with pytest.raises(ConfigError, match="set perception.coco_precision=auto or fp32$"):
        Bf16CenterNet(fp32_model)
    with pytest.raises(ConfigError, match="set perception.coco_precision=auto or fp32$"):
        build_frame_detector(PerceptionConfig(kind="coco", coco_precision="bf16"))
