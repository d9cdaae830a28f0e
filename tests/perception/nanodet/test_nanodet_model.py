"""NanoDet: the GFL decoding on hand-made maps, and the fetched network on a photograph and on renders."""

import cv2
import matplotlib.cbook
import numpy as np
import pytest
import torch

from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.ap import box_iou
from avsim.perception.factory import build_frame_detector, build_perception
from avsim.perception.nanodet.model import decode, load_nanodet
from avsim.perception.nanodet.network import feature_sizes
from avsim.perception.yolo.infer import YoloRunner
from avsim.vehicle.physics import FRONT_BUMPER_X_M

THRESHOLD = SimConfig().policy.conf_threshold


@pytest.fixture(scope="module")
def nanodet():
    return load_nanodet()


def test_a_side_is_the_expectation_of_its_bins_times_the_stride_from_the_cell_centre():
    height, width = 64, 96
    outputs = []
    for (rows, cols) in feature_sizes(height, width):
        cls = torch.zeros(1, rows * cols, 80)
        sides = torch.full((1, rows * cols, 44), -1e4)
        sides[..., 0::11] = 0.0  # every side at bin 0 ...
        outputs.append((cls, sides))
    # ... but at stride 16, cell (row 1, column 2): left at bin 3, top at 1, right at 2, bottom half at 4 and 6.
    cell = 1 * feature_sizes(height, width)[1][1] + 2
    sides = outputs[1][1]
    sides[0, cell, :] = -1e4
    sides[0, cell, [3, 11 + 1, 22 + 2, 33 + 4, 33 + 6]] = 0.0
    outputs[1][0][0, cell, 11] = 0.9
    boxes, scores = decode(tuple(outputs), (height, width))
    index = sum(r * c for r, c in feature_sizes(height, width)[:1]) + cell
    centre_x, centre_y = (2 + 0.5) * 16, (1 + 0.5) * 16
    assert torch.allclose(boxes[0, index], torch.tensor([centre_x - 48, centre_y - 16, centre_x + 32, centre_y + 80]))
    assert scores[0, index, 11] == pytest.approx(0.9) and boxes.shape[1] == scores.shape[1] == 8 * 12 + 4 * 6 + 2 * 3


def test_the_network_runs_at_any_size_in_multiples_of_32(nanodet):
    with torch.inference_mode():
        for height, width in ((416, 416), (256, 352)):
            boxes, scores = nanodet(torch.zeros(1, 3, height, width))
            assert boxes.shape[1] == scores.shape[1] == sum(r * c for r, c in feature_sizes(height, width))
        with pytest.raises(ValueError, match="multiples of 32"):
            nanodet.network(torch.zeros(1, 3, 100, 416))


def test_it_finds_the_person_in_a_photograph(nanodet):
    # Grace Hopper's portrait, shipped with matplotlib: the whole frame is one person, with her tie.
    image = cv2.cvtColor(cv2.imread(matplotlib.cbook.get_sample_data("grace_hopper.jpg", asfileobj=False)), cv2.COLOR_BGR2RGB)
    detections = YoloRunner(nanodet, "resize", 1.0, 0.3, iou_threshold=0.6).detect(image, "front")
    best = detections[0]
    assert best.class_name == "person" and best.confidence > 0.7
    x0, y0, x1, y1 = best.box_xyxy_px
    assert (x1 - x0) * (y1 - y0) > 0.8 * image.shape[0] * image.shape[1]
    assert "tie" in {d.class_name for d in detections}


def test_the_closed_loop_perception_finds_the_clean_sign_near():
    loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": "nanodet"}}))
    oracle = build_perception(PerceptionConfig(kind="oracle", min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
    try:
        assert loop.perception.name == "nanodet"
        loop.vehicle.place(loop.scene.stop_line_x_m - 15.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        truth = [d for d in oracle.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
        found = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
        iou = box_iou(np.asarray([d.box_xyxy_px for d in found], float).reshape(-1, 4), np.asarray([truth[0].box_xyxy_px], float))
        assert len(truth) == 1 and any(d.confidence >= THRESHOLD and i >= 0.5 for d, i in zip(found, iou[:, 0])), found
    finally:
        loop.close()


def test_the_frame_detector_is_nanodet_on_the_region_enlarged_by_2():
    detector = build_frame_detector(PerceptionConfig(kind="nanodet"))
    assert detector.input_mode == "upscale" and detector.upscale == 2.0 and detector.iou_threshold == 0.6
