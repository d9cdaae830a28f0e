"""Which geoms a camera cannot see: bounding spheres wholly outside its view frustum.

Mesa's llvmpipe, avsim's CPU rasteriser, pays for every geom a render submits, seen or not:
its vertices are transformed, clipped and set up before they are found to cover no pixel. In a
town most geoms are behind or beside the car (Town07: 91 of 136 at 60 m before the sign;
Town10: 306 of 387), and leaving them out of the scene cuts a front-camera render by about a
fifth, with the same pixels.

A geom is left out only when its bounding sphere (`model.geom_rbound` about `data.geom_xpos`)
lies wholly behind the camera or wholly outside one of the frustum's four side planes, so no
part of it can reach a pixel. The test is conservative: a sphere that only crosses a corner
region outside the frustum is kept (drawn, and clipped by the rasteriser, as before).

Culling is only exact when nothing outside the view can change a pixel inside it, so
`cullable` refuses it for scenes with shadow-casting lights (a geom behind the camera can cast
a shadow into the view), reflective materials (a mirror shows what is behind), and cameras whose
projection is not MuJoCo's symmetric perspective from `fovy` (orthographic, or set by sensor size
and intrinsics).

Frames: MuJoCo's camera frame, x right, y up, looking along -z; `data.cam_xmat` holds its axes as
columns in world coordinates.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

# The sphere must clear a plane by this much before its geom is left out: a margin for the float32
# arithmetic of the GL pipeline, far below a geom's size and far above rounding [m].
MARGIN_M = 1e-3


def cullable(model: mujoco.MjModel, camera_id: int) -> bool:
    """True when leaving out-of-view geoms out of `camera_id`'s renders cannot change a pixel."""
    if model.nlight and np.any(model.light_castshadow):
        return False
    if model.nmat and np.any(model.mat_reflectance > 0):
        return False
    if model.cam_projection[camera_id] != mujoco.mjtProjection.mjPROJ_PERSPECTIVE or np.any(model.cam_sensorsize[camera_id] > 0):
        return False
    return True


def outside_view(model: mujoco.MjModel, data: mujoco.MjData, camera_id: int, aspect: float) -> np.ndarray:
    """(ngeom,) bool: the geoms `camera_id` cannot see at the state `data` holds.

    aspect: the image's width / height (MuJoCo's `fovy` is the vertical field of view; the
    horizontal one follows from the viewport). Geoms without a bounding sphere (planes, whose
    `geom_rbound` is 0) are never out of view.
    """
    radius_m = model.geom_rbound
    to_geom_m = data.geom_xpos - data.cam_xpos[camera_id]
    in_camera = to_geom_m @ data.cam_xmat[camera_id].reshape(3, 3)  # (ngeom, 3) camera-frame coordinates
    right_m, up_m, depth_m = in_camera[:, 0], in_camera[:, 1], -in_camera[:, 2]
    tan_half_y = math.tan(math.radians(model.cam_fovy[camera_id]) / 2)
    tan_half_x = tan_half_y * aspect
    reach_m = radius_m + MARGIN_M
    hidden = depth_m < -reach_m  # wholly behind the camera
    for lateral_m, tan_half in ((right_m, tan_half_x), (-right_m, tan_half_x), (up_m, tan_half_y), (-up_m, tan_half_y)):
        # Signed distance from the side plane lateral = tan_half * depth, positive outside the frustum.
        hidden |= (lateral_m - tan_half * depth_m) / math.hypot(1.0, tan_half) > reach_m
    return hidden & (radius_m > 0)
