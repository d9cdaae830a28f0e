"""The parts of a run that never move, logged once as static rerun data.

All positions are in the MuJoCo world frame (x along the road towards the stop
line, y left, z up) [m], except the car body boxes, which are in the car body frame
(x forward, origin midway between the axles at wheel-centre height).
"""

from __future__ import annotations

import mujoco
import numpy as np
import rerun as rr

from avsim.recording import paths
from avsim.sensors.camera import Intrinsics
from avsim.world.road import APPROACH_LENGTH_M, ROAD_END_X_M
from avsim.world.scene import CAR_PREFIX, SceneInfo

# Geoms of models/car.xml drawn as the car's body boxes (the shell the cameras do not see).
CAR_BOX_GEOMS = ("chassis", "cabin")
# Lines painted on the road are drawn this high so they are not hidden in the asphalt [m].
ROAD_LINE_Z_M = 0.03
# Distance of the drawn image plane from the camera centre in the 3D view [m]: small,
# so the frustum does not hide the car.
IMAGE_PLANE_DIST_M = 1.0

_RED = (220, 30, 30)
_GREY = (160, 160, 160)
_WHITE = (240, 240, 240)


def log_world(rec: rr.RecordingStream, model: mujoco.MjModel, scene: SceneInfo) -> None:
    """World axes, car body boxes, stop sign, stop line and road edges."""
    rec.log(paths.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True, strict=True)
    _log_car_body(rec, model)
    _log_stop_sign(rec, scene)
    _log_road(rec, scene)


def log_pinhole(rec: rr.RecordingStream, camera: str, intrinsics: Intrinsics) -> None:
    """The camera's intrinsics; its image pixels follow avsim's convention (pixel i covers [i, i + 1))."""
    rec.log(
        paths.camera_image(camera),
        rr.Pinhole(
            focal_length=intrinsics.f_px,
            principal_point=intrinsics.principal_point_px,
            width=intrinsics.width_px,
            height=intrinsics.height_px,
            # MuJoCo cameras: x right, y up, looking along -z ("right, up, back").
            camera_xyz=rr.ViewCoordinates.RUB,
            image_plane_distance=IMAGE_PLANE_DIST_M,
        ),
        static=True,
        strict=True,
    )


def _log_car_body(rec: rr.RecordingStream, model: mujoco.MjModel) -> None:
    # Read from the compiled model, so the drawn car follows models/car.xml.
    geoms = [model.geom(CAR_PREFIX + name) for name in CAR_BOX_GEOMS]
    rec.log(
        paths.CAR_BODY,
        rr.Boxes3D(
            centers=[np.asarray(g.pos) for g in geoms],
            half_sizes=[np.asarray(g.size) for g in geoms],
            colors=[(np.asarray(g.rgba[:3]) * 255).astype(np.uint8) for g in geoms],
            fill_mode=rr.components.FillMode.Solid,
        ),
        static=True,
        strict=True,
    )


def _log_stop_sign(rec: rr.RecordingStream, scene: SceneInfo) -> None:
    sign = scene.stop_sign
    outline = sign.corners_m()
    base = np.asarray(sign.base_pos_m, dtype=float)
    post_top = base + np.array([0.0, 0.0, sign.bottom_height_m + sign.shape.height_m / 2])
    rec.log(
        paths.STOP_SIGN,
        rr.LineStrips3D(
            [np.vstack([outline, outline[:1]]), np.vstack([base, post_top])],
            colors=[_RED, _GREY],
            radii=[0.03, 0.035],
            labels=[sign.name, ""],
        ),
        static=True,
        strict=True,
    )


def _log_road(rec: rr.RecordingStream, scene: SceneInfo) -> None:
    layout = scene.layout
    x_line = scene.stop_line_x_m
    # The stop line crosses the travelled direction's lanes only, from the right edge
    # to the centre (the near edge of the paint, the reference of stop_line_dist_m).
    lanes_width_m = layout.lanes_per_direction * layout.lane_width_m
    y_right = layout.lane_edge_y_m
    rec.log(
        paths.STOP_LINE,
        rr.LineStrips3D(
            [[(x_line, y_right, ROAD_LINE_Z_M), (x_line, y_right + lanes_width_m, ROAD_LINE_Z_M)]],
            colors=[_WHITE],
            radii=[0.15],
            labels=["stop line"],
        ),
        static=True,
        strict=True,
    )
    x0, x1 = x_line - APPROACH_LENGTH_M, ROAD_END_X_M
    edges = [[(x0, y, ROAD_LINE_Z_M), (x1, y, ROAD_LINE_Z_M)] for y in (-layout.half_width_m, layout.half_width_m)]
    rec.log(paths.ROAD, rr.LineStrips3D(edges, colors=[_GREY], radii=[0.08]), static=True, strict=True)
