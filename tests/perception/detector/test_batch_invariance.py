"""The own detector's `detect_many`: a frame's detections do not depend on the frames beside it.

The lock-step batch rests on this (`avsim.perception.detector.infer`, "Batches"): under bf16 the
frames share one network call, whose per-image maps oneDNN must compute as it does for one image;
under fp32 each frame gets its own batch-1 call. Measured on this machine's kernels, not assumed.
"""

import pytest

from avsim.bench.speed import _approach_frames
from avsim.config import SimConfig
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.perception.detector.weights import resolve_weights_path
from avsim.sensors.regions import STUDY_REGIONS_PX
from helpers import needs_bf16

FRONT_ROI = STUDY_REGIONS_PX["front"]


@pytest.fixture(scope="module")
def frames():
    return _approach_frames(SimConfig(), count=8)


@pytest.mark.parametrize("precision", ["fp32", pytest.param("bf16", marks=needs_bf16)])
def test_every_batch_size_gives_each_frame_its_lone_detections(frames, precision):
    runner = SignDetectorRunner(resolve_weights_path(""), conf_threshold=0.05, num_threads=1, precision=precision)
    alone = [runner.detect(frame, "front", region_px=FRONT_ROI) for frame in frames]
    assert any(alone), "the approach frames should hold the sign"
    for size in (2, 3, 8):
        together = runner.detect_many([(frame, "front", FRONT_ROI) for frame in frames[:size]])
        assert together == alone[:size], f"batch of {size}"
    # frames of different shapes (a whole frame beside region crops) in one call
    mixed = runner.detect_many([(frames[0], "front", None), (frames[1], "front", FRONT_ROI), (frames[2], "side", None)])
    assert mixed == [runner.detect(frames[0], "front"), alone[1], runner.detect(frames[2], "side")]


@needs_bf16
def test_bf16_moves_scores_by_rounding_only(frames):
    fp32 = SignDetectorRunner(resolve_weights_path(""), conf_threshold=0.3, num_threads=1)
    bf16 = SignDetectorRunner(resolve_weights_path(""), conf_threshold=0.3, num_threads=1, precision="bf16")
    compared = 0
    for frame in frames:
        a, b = fp32.detect(frame, "front", region_px=FRONT_ROI), bf16.detect(frame, "front", region_px=FRONT_ROI)
        assert [d.class_name for d in a] == [d.class_name for d in b]
        for x, y in zip(a, b):
            assert abs(x.confidence - y.confidence) < 0.02
            assert max(abs(p - q) for p, q in zip(x.box_xyxy_px, y.box_xyxy_px)) < 2.0
            compared += 1
    assert compared >= 4
