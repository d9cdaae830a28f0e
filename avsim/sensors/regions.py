"""Each camera's deployed region of interest, as an angular region that follows the camera.

The study's regions were drawn in the pixels of its 640x480 camera (f = 895.7 px): the front
camera's [288, 0, 640, 256] and the side camera's [0, 0, 640, 256]. Every stop sign of the study's
towns and placements stands right of the road and above the camera, so the regions hold what lies
right of a line 32 px (2.0 deg) left of the optical axis (front only) and above a line 16 px
(1.0 deg) below the horizon, out to the frame's edges. Here those lines are angles, so that a
camera of another resolution or field of view (camera.preset) searches the same part of the world.
A region set in `perception.front_roi_px` / `side_roi_px` is taken as it is, in the camera's pixels.
"""

from __future__ import annotations

from collections.abc import Mapping

from avsim.config import CameraConfig, PerceptionConfig
from avsim.sensors.camera import intrinsics_for

Region = tuple[int, int, int, int]  # (x0, y0, x1, y1) [px]

# The region's inner edges as tan(angle) off the optical axis (x right, y down), from the study's pixels.
_STUDY = intrinsics_for("front", CameraConfig(preset="study"))
FRONT_LEFT_TAN = (288 - _STUDY.principal_point_px[0]) / _STUDY.f_px  # 2.0 deg left of the axis
BELOW_HORIZON_TAN = (256 - _STUDY.principal_point_px[1]) / _STUDY.f_px  # 1.0 deg below the horizon


def deployed_region_px(camera: str, config: CameraConfig) -> Region:
    """Camera "front" or "side"'s deployed region (x0, y0, x1, y1) [px] under `config`, rounded to whole pixels."""
    intrinsics = intrinsics_for(camera, config)
    cx, cy = intrinsics.principal_point_px
    x0 = round(cx + intrinsics.f_px * FRONT_LEFT_TAN) if camera == "front" else 0
    y1 = round(cy + intrinsics.f_px * BELOW_HORIZON_TAN)
    return max(x0, 0), 0, intrinsics.width_px, min(y1, intrinsics.height_px)


def regions_px(perception: PerceptionConfig, camera: CameraConfig) -> dict[str, Region]:
    """{"front": region, "side": region} [px]: the perception's set regions, else the camera's deployed ones."""
    return resolve_regions_px({"front": perception.front_roi_px, "side": perception.side_roi_px}, camera)


def resolve_regions_px(set_regions: Mapping[str, tuple[int, ...]], camera: CameraConfig) -> dict[str, Region]:
    """Each camera's region in `set_regions` ((x0, y0, x1, y1) [px], or () for the deployed one) as pixels of `camera`."""
    return {name: tuple(region) if region else deployed_region_px(name, camera)  # type: ignore[misc]
            for name, region in set_regions.items()}


# The default perception's regions with the study camera: [288, 0, 640, 256] and [0, 0, 640, 256].
STUDY_REGIONS_PX = regions_px(PerceptionConfig(), CameraConfig())
