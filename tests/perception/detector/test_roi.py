"""Region-of-interest detection: the crop's geometry, and that it is exact inside the region."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.detector.infer import SignDetectorRunner, _in_frame
from avsim.perception.detector.letterbox import letterbox
from avsim.perception.detector.weights import SHIPPED_WEIGHTS
from avsim.perception.detector.postprocess import decode
from avsim.perception.detector.roi import ALIGN_PX, CONTEXT_PX, clip_region, crop_for
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.sensors.regions import STUDY_REGIONS_PX

DEFAULT = SimConfig().perception
REGIONS = {"front default": STUDY_REGIONS_PX["front"], "side default": STUDY_REGIONS_PX["side"],
           "centre": (200, 150, 440, 330), "bottom right": (400, 300, 640, 480)}


@pytest.mark.parametrize("region", REGIONS.values(), ids=REGIONS.keys())
def test_crop_is_aligned_and_reaches_the_context_beyond_every_inner_edge(region):
    x0, y0, x1, y1 = crop_for(region, 640, 480)
    assert all(v % ALIGN_PX == 0 for v in (x0, y0, x1 - x0, y1 - y0))
    assert x0 == 0 or x0 <= region[0] - CONTEXT_PX
    assert y0 == 0 or y0 <= region[1] - CONTEXT_PX
    assert x1 == 640 or x1 >= region[2] + CONTEXT_PX
    assert y1 == 480 or y1 >= region[3] + CONTEXT_PX


def test_default_front_crop_is_well_under_the_whole_frame():
    x0, y0, x1, y1 = crop_for(STUDY_REGIONS_PX["front"], 640, 480)
    assert (x1 - x0) * (y1 - y0) <= 0.65 * 640 * 480


def test_crop_is_refused_where_the_image_side_is_not_aligned():
    assert crop_for((500, 0, 630, 100), 630, 470) is None  # must reach the 630 px border: not a multiple of 32
    assert crop_for((0, 0, 100, 100), 630, 470) == (0, 0, 256, 256)  # stops short of it: fine


def test_region_outside_the_image_is_a_clear_error():
    with pytest.raises(ValueError, match="outside the 640x480 image"):
        clip_region((700, 0, 800, 100), 640, 480)
    assert clip_region((-5, -5, 900, 900), 640, 480) == (0, 0, 640, 480)


@pytest.fixture(scope="module")
def runner():
    return SignDetectorRunner(SHIPPED_WEIGHTS, conf_threshold=0.1, num_threads=1)


@pytest.fixture(scope="module")
def rendered_frames():
    """Front and side frames of Town07 with the clean sign 12, 30 and 60 m ahead."""
    loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": "detector"}}))
    frames = []
    try:
        for dist_m in (12.0, 30.0, 60.0):
            loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            frames += [(loop.rig.render_rgb(loop.data, camera), camera) for camera in ("front", "side")]
    finally:
        loop.close()
    return frames


@pytest.mark.parametrize("region", REGIONS.values(), ids=REGIONS.keys())
def test_network_on_the_crop_equals_the_whole_frame_bit_for_bit_inside_the_region(runner, region):
    image = torch.rand(1, 3, 480, 640, generator=torch.Generator().manual_seed(1))
    x0, y0, x1, y1 = crop_for(region, 640, 480)
    with torch.inference_mode():
        whole = runner.model(image.contiguous(memory_format=torch.channels_last))
        cropped = runner.model(image[:, :, y0:y1, x0:x1].contiguous(memory_format=torch.channels_last))
    for stride, full_map, crop_map in zip(runner.model.strides, whole, cropped):
        # cells of the whole map whose centres lie in the region, and the same cells in the crop's map
        cols = [j for j in range(full_map.shape[3]) if region[0] <= (j + 0.5) * stride < region[2]]
        rows = [i for i in range(full_map.shape[2]) if region[1] <= (i + 0.5) * stride < region[3]]
        inside = full_map[:, :, rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
        same = crop_map[:, :, rows[0] - y0 // stride:rows[-1] + 1 - y0 // stride, cols[0] - x0 // stride:cols[-1] + 1 - x0 // stride]
        assert torch.equal(inside, same), f"stride {stride}: max difference {(inside - same).abs().max():.3g}"


def _key(d):
    return d.class_name, d.confidence, d.box_xyxy_px, d.truncated


def _whole_frame_then_region(runner, frame, camera, region):
    """The whole frame's network output, with only the region's cells decoded: what a crop must equal."""
    tensor, box = letterbox(frame, runner.input_size)
    with torch.inference_mode():
        det = decode(runner.model(tensor.unsqueeze(0)), runner.conf_threshold, runner.model.strides, region_px=region)[0]
    return runner._to_detections(_in_frame(det, box), frame.shape[1], frame.shape[0], camera)


@pytest.mark.parametrize("region", REGIONS.values(), ids=REGIONS.keys())
def test_region_detections_equal_the_whole_frame_cells_in_the_region(runner, rendered_frames, region):
    found_stop = False
    for frame, camera in rendered_frames:
        expected = [_key(d) for d in _whole_frame_then_region(runner, frame, camera, region)]
        assert [_key(d) for d in runner.detect(frame, camera, region_px=region)] == expected
        found_stop = found_stop or any(key[0] == "stop_sign" for key in expected)
    if region in (STUDY_REGIONS_PX["front"], STUDY_REGIONS_PX["side"]):
        assert found_stop, "the default region should hold the clean stop sign in these frames"


def test_default_regions_hold_the_stop_sign_of_every_frame(runner, rendered_frames):
    for frame, camera in rendered_frames:
        region = STUDY_REGIONS_PX["front"] if camera == "front" else STUDY_REGIONS_PX["side"]
        whole = [_key(d) for d in runner.detect(frame, camera) if d.class_name == "stop_sign" and d.confidence >= 0.5]
        in_region = [_key(d) for d in runner.detect(frame, camera, region_px=region)]
        assert all(key in in_region for key in whole), f"{camera}: a confident stop sign lies outside the default region"


def test_a_letterboxed_image_is_searched_whole_and_filtered_to_the_region(runner, rendered_frames):
    frame, camera = rendered_frames[2]  # front at 30 m
    small = np.ascontiguousarray(frame[::2, ::2])  # 320x240: letterboxed up, no exact crop
    region = (144, 0, 320, 128)
    whole = {_key(d) for d in runner.detect(small, camera)}
    in_region = [_key(d) for d in runner.detect(small, camera, region_px=region)]
    assert set(in_region) <= whole
