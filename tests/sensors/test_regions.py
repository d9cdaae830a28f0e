"""The deployed regions of interest: the study's pixels at the study camera, the same angles under any preset."""

import math

import pytest

from avsim.config import CAMERA_PRESETS, CameraConfig, PerceptionConfig
from avsim.sensors.camera import intrinsics_for
from avsim.sensors.regions import (BELOW_HORIZON_TAN, FRONT_LEFT_TAN, STUDY_REGIONS_PX, deployed_region_px,
                                   regions_px)


def test_the_study_camera_gets_the_study_regions_exactly():
    assert STUDY_REGIONS_PX == {"front": (288, 0, 640, 256), "side": (0, 0, 640, 256)}
    assert FRONT_LEFT_TAN == pytest.approx(math.tan(math.radians(-2.045)), abs=1e-4)
    assert BELOW_HORIZON_TAN == pytest.approx(math.tan(math.radians(1.023)), abs=1e-4)


@pytest.mark.parametrize("preset", sorted(CAMERA_PRESETS))
@pytest.mark.parametrize("camera", ["front", "side"])
def test_a_preset_searches_the_same_angles_out_to_its_frame_edges(preset, camera):
    config = CameraConfig(preset=preset)
    intrinsics = intrinsics_for(camera, config)
    cx, cy = intrinsics.principal_point_px
    x0, y0, x1, y1 = deployed_region_px(camera, config)
    # The inner edges sit at the study's angles, to the half pixel that rounding allows.
    assert (y1 - cy) / intrinsics.f_px == pytest.approx(BELOW_HORIZON_TAN, abs=0.5 / intrinsics.f_px)
    if camera == "front":
        assert (x0 - cx) / intrinsics.f_px == pytest.approx(FRONT_LEFT_TAN, abs=0.5 / intrinsics.f_px)
    else:
        assert x0 == 0
    assert (y0, x1) == (0, intrinsics.width_px)


def test_the_automotive_regions_scale_with_its_focal_length():
    config = CameraConfig(preset="automotive_1080p")
    scale = config.f_px / CameraConfig().f_px
    x0, _, x1, y1 = deployed_region_px("front", config)
    assert (x0, x1, y1) == (894, 1920, 573)
    assert 960 - x0 == pytest.approx(32 * scale, abs=0.5) and y1 - 540 == pytest.approx(16 * scale, abs=0.5)


def test_a_set_region_is_taken_as_it_is_under_any_preset():
    perception = PerceptionConfig(front_roi_px=(0, 0, 100, 50))
    regions = regions_px(perception, CameraConfig(preset="automotive_1080p"))
    assert regions == {"front": (0, 0, 100, 50), "side": (0, 0, 1920, 573)}
