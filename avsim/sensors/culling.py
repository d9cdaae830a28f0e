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
# The whole image, in normalised device coordinates: (left, right, bottom, top).
FULL_VIEW_NDC = (-1.0, 1.0, -1.0, 1.0)


def has_reflective_material(model: mujoco.MjModel) -> bool:
    """Whether MuJoCo draws a reflection in this model: a mirror shows geoms out of view, and MuJoCo draws it
    through the stencil buffer."""
    return bool(model.nmat and np.any(model.mat_reflectance > 0))


def cullable(model: mujoco.MjModel, camera_id: int) -> bool:
    """True when leaving out-of-view geoms out of `camera_id`'s renders cannot change a pixel."""
    if model.nlight and np.any(model.light_castshadow):
        return False
    if has_reflective_material(model):
        return False
    if model.cam_projection[camera_id] != mujoco.mjtProjection.mjPROJ_PERSPECTIVE or np.any(model.cam_sensorsize[camera_id] > 0):
        return False
    return True


def outside_view(model: mujoco.MjModel, data: mujoco.MjData, camera_id: int, aspect: float,
                 window_ndc: tuple[float, float, float, float] = FULL_VIEW_NDC) -> np.ndarray:
    """(ngeom,) bool: the geoms `camera_id` cannot see at the state `data` holds.

    aspect: the image's width / height (MuJoCo's `fovy` is the vertical field of view; the
    horizontal one follows from the viewport). Geoms without a bounding sphere (planes, whose
    `geom_rbound` is 0) are never out of view.

    window_ndc: (left, right, bottom, top), the part of the image that counts, in normalised device
    coordinates (x from -1 at the left edge to 1 at the right, y from -1 at the bottom to 1 at the
    top); a geom outside that part's frustum is out of view. Pixels inside the window are the same
    with or without such geoms (see `window_of_region`).
    """
    radius_m = model.geom_rbound
    to_geom_m = data.geom_xpos - data.cam_xpos[camera_id]
    in_camera = to_geom_m @ data.cam_xmat[camera_id].reshape(3, 3)  # (ngeom, 3) camera-frame coordinates
    right_m, up_m, depth_m = in_camera[:, 0], in_camera[:, 1], -in_camera[:, 2]
    tan_half_y = math.tan(math.radians(model.cam_fovy[camera_id]) / 2)
    tan_half_x = tan_half_y * aspect
    left, right, bottom, top = window_ndc
    reach_m = radius_m + MARGIN_M
    hidden = depth_m < -reach_m  # wholly behind the camera
    # Each side plane is lateral = slope * depth; `sign` turns the lateral axis so that outside is positive.
    for lateral_m, slope, sign in ((right_m, tan_half_x * right, 1.0), (right_m, tan_half_x * left, -1.0),
                                   (up_m, tan_half_y * top, 1.0), (up_m, tan_half_y * bottom, -1.0)):
        # Signed distance from the plane, positive outside the frustum.
        hidden |= sign * (lateral_m - slope * depth_m) / math.hypot(1.0, slope) > reach_m
    return hidden & (radius_m > 0)


def window_of_region(region_px: tuple[int, int, int, int], width_px: int, height_px: int) -> tuple[float, float, float, float]:
    """`outside_view`'s window_ndc for the pixels region_px = (x0, y0, x1, y1) of a width_px x height_px
    image (row 0 at the top, end-exclusive), grown by one pixel on every side (clipped to the image).

    The window's edges are pixel edges, and a pixel is drawn from samples inside it, so a geom wholly
    outside the window's frustum reaches none of the region's pixels; the pixel of margin keeps that true
    whatever the rasteriser's rounding.
    """
    x0, y0, x1, y1 = region_px
    x0, y0, x1, y1 = max(0, x0 - 1), max(0, y0 - 1), min(width_px, x1 + 1), min(height_px, y1 + 1)
    return 2 * x0 / width_px - 1, 2 * x1 / width_px - 1, 1 - 2 * y1 / height_px, 1 - 2 * y0 / height_px
