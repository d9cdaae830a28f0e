"""`native_pixels`: a frame larger than the network's input is also searched at its own pixels.

At the study's 640x480 nothing changes. Under the 1920x1080 automotive camera the letterbox alone
shrinks the frame 3x; the native pass finds the far sign the letterbox loses, and the merged result
keeps the near sign, which at full resolution is larger than any sign in the training frames.
"""

from __future__ import annotations

import numpy as np
import pytest

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.perception.detector.weights import SHIPPED_WEIGHTS
from avsim.sensors.regions import deployed_region_px
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from helpers import needs_bf16

THRESHOLD = 0.5
FAR_M, NEAR_M = 110.0, 12.0


def _key(d):
    return d.class_name, d.confidence, d.box_xyxy_px, d.truncated


def _front_frames(preset: str, dists_m: tuple[float, ...]) -> tuple[list[np.ndarray], tuple[int, int, int, int]]:
    """Front frames of Town07 with the clean sign `dists_m` ahead of the bumper, and the front region."""
    loop = ClosedLoop(with_overrides(SimConfig(), {"camera": {"preset": preset}}))
    try:
        frames = []
        for dist_m in dists_m:
            sign_x_m = loop.scene.stop_sign.base_pos_m[0]
            loop.vehicle.place(sign_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            frames.append(loop.rig.render_rgb(loop.data, "front"))
        return frames, deployed_region_px("front", loop.config.camera)
    finally:
        loop.close()


@pytest.fixture(scope="module")
def automotive():
    """((far frame, near frame), front region) under the automotive camera, rendered once for the module."""
    return _front_frames("automotive_1080p", (FAR_M, NEAR_M))


@pytest.fixture(scope="module")
def runners():
    return {native: SignDetectorRunner(SHIPPED_WEIGHTS, conf_threshold=0.1, num_threads=1, native_pixels=native)
            for native in (False, True)}


def _stop_scores(detections) -> list[float]:
    return [d.confidence for d in detections if d.class_name == "stop_sign" and d.confidence >= THRESHOLD]


def test_at_the_study_camera_the_native_pass_changes_nothing(runners):
    frames, region = _front_frames("study", (30.0,))
    for region_px in (region, None):
        assert ([_key(d) for d in runners[True].detect(frames[0], "front", region_px=region_px)]
                == [_key(d) for d in runners[False].detect(frames[0], "front", region_px=region_px)])


def test_under_the_automotive_camera_the_native_pass_finds_the_far_sign_and_keeps_the_near_one(runners, automotive):
    (far, near), region = automotive
    assert far.shape == (1080, 1920, 3)
    assert not _stop_scores(runners[False].detect(far, "front", region_px=region)), \
        "the letterboxed 1080p frame should lose the sign at 110 m (3x fewer pixels)"
    assert _stop_scores(runners[True].detect(far, "front", region_px=region))
    assert _stop_scores(runners[False].detect(near, "front", region_px=region))
    merged = runners[True].detect(near, "front", region_px=region)
    assert _stop_scores(merged)
    # The merge is NMS over both passes: no two stop-sign boxes left on the one sign.
    stops = [d for d in merged if d.class_name == "stop_sign" and d.confidence >= THRESHOLD]
    assert len(stops) == 1


def test_a_frame_without_a_region_is_searched_whole_at_its_own_pixels(runners, automotive):
    (far, _), region = automotive
    whole = _stop_scores(runners[True].detect(far, "front"))
    assert whole and max(whole) == pytest.approx(max(_stop_scores(runners[True].detect(far, "front", region_px=region))), abs=0.05)


@pytest.mark.parametrize("precision", ["fp32", pytest.param("bf16", marks=needs_bf16)])
def test_the_batch_gives_each_frame_what_it_gets_alone(precision, automotive):
    frames, region = automotive
    for native in (False, True):
        runner = SignDetectorRunner(SHIPPED_WEIGHTS, conf_threshold=0.1, num_threads=1, precision=precision,
                                    native_pixels=native)
        alone = [[_key(d) for d in runner.detect(f, "front", region_px=region)] for f in frames]
        together = runner.detect_many([(f, "front", region) for f in frames])
        assert [[_key(d) for d in found] for found in together] == alone
