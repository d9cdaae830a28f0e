"""Read the geometry `avsim.attacks.warp` needs from a live MuJoCo scene.

A `SignView` is one camera looking at one sign: the camera's intrinsics and pose, and
where the corners of the sign's texture square are in the world. The texture square
is the footprint `signs.py` maps the texture onto: texture u grows towards the sign's
local -y (the viewer's right) and v grows downwards, the texture's edges sitting on the
outline's bounding box (for the stop sign the octagon is inscribed in the square).
"""

from __future__ import annotations

from contextlib import contextmanager
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import mujoco
import numpy as np
import torch

from avsim.attacks.warp import UNIT_SQUARE_ST, project_points_px
from avsim.sensors.camera import CameraPose, CameraRig, Intrinsics
from avsim.world.signs import PlacedSign, SignShape

# CameraRig leaves geom group 3 out of every render; a face moved there is hidden.
_HIDDEN_GROUP = 3
# fillPoly takes fixed-point vertices; 4 fractional bits keep the outline sub-texel exact.
_SHIFT = 4


def texture_corners_m(sign: PlacedSign) -> np.ndarray:
    """World positions (4, 3) [m] of texture (s, t) = (0, 0), (1, 0), (1, 1), (0, 1) on the face.

    Inverts signs.py's mapping u = 0.5 - y / width_m, v = 0.5 - z / height_m (y = viewer's
    left, z up, in the face plane), so (0, 0) is the top-left corner as seen from the front.
    """
    shape = sign.shape
    st = np.asarray(UNIT_SQUARE_ST)
    yz = np.column_stack([(0.5 - st[:, 0]) * shape.width_m, (0.5 - st[:, 1]) * shape.height_m])
    return sign.face_points_m(yz)


def face_alpha(shape: SignShape, height_px: int, width_px: int) -> torch.Tensor:
    """Coverage (1, H_tex, W_tex) in [0, 1] of the sign outline on its texture square.

    Texel (i, j) is 1 inside the outline the face mesh is cut to, 0 outside (the texture's
    unused grey corners), anti-aliased along the outline.
    """
    yz = np.asarray(shape.outline_yz)
    s = 0.5 - yz[:, 0] / shape.width_m
    t = 0.5 - yz[:, 1] / shape.height_m
    # OpenCV puts pixel centres at integers; ours (texel i covers [i, i + 1)) are at i + 0.5.
    pts = np.column_stack([s * width_px - 0.5, t * height_px - 0.5])
    img = np.zeros((height_px, width_px), np.uint8)
    cv2.fillPoly(img, [np.round(pts * (1 << _SHIFT)).astype(np.int32)], 255, cv2.LINE_AA, _SHIFT)
    return torch.from_numpy(img).float().div(255.0)[None]


@dataclass(frozen=True)
class SignView:
    """One camera's view of one sign: world frame [m], camera as in `avsim.sensors.camera`."""

    intrinsics: Intrinsics
    pose: CameraPose
    texture_corners_m: np.ndarray  # (4, 3), texture (s, t) corners in UNIT_SQUARE_ST order

    @property
    def image_hw(self) -> tuple[int, int]:
        """(height, width) [px] of the camera image the view is in."""
        return self.intrinsics.height_px, self.intrinsics.width_px

    def corner_depths_m(self) -> np.ndarray:
        """Depth (4,) [m] of each texture corner along the optical axis."""
        return np.array([self.pose.depth_m(p) for p in self.texture_corners_m])


def sign_view(rig: CameraRig, data: mujoco.MjData, camera: str, sign: PlacedSign) -> SignView:
    """The current view of `sign` from the car camera `camera` (after mj_forward on `data`)."""
    return SignView(rig.intrinsics(camera), rig.pose(data, camera), texture_corners_m(sign))


def corners_px(views: list[SignView], dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Image positions (B, 4, 2) [px] of each view's texture corners, for `warp_texture`.

    Raises ValueError if a corner is behind a camera: the homography would fold the face.
    """
    for k, view in enumerate(views):
        if (view.corner_depths_m() <= 0).any():
            raise ValueError(f"view {k}: the sign's texture square is (partly) behind the camera")
    points = torch.as_tensor(np.stack([v.texture_corners_m for v in views]), dtype=dtype)
    position = torch.as_tensor(np.stack([v.pose.position_m for v in views]), dtype=dtype)
    rotation = torch.as_tensor(np.stack([v.pose.rotation for v in views]), dtype=dtype)
    f_px = torch.as_tensor([v.intrinsics.f_px for v in views], dtype=dtype)
    pp = torch.as_tensor([v.intrinsics.principal_point_px for v in views], dtype=dtype)
    uv, _ = project_points_px(points, position, rotation, f_px, pp)
    return uv


@contextmanager
def face_hidden(model: mujoco.MjModel, sign: PlacedSign) -> Iterator[None]:
    """Hide the sign's face from `CameraRig` renders inside the block (its post stays).

    Used to render the background a warped face is composited over: with the face
    hidden, the pixels along the outline (which the warp covers only partly) blend
    with what really lies behind the sign rather than with the clean sign's own edge.
    """
    gid = model.geom(sign.face_geom).id
    group = int(model.geom_group[gid])
    model.geom_group[gid] = _HIDDEN_GROUP
    try:
        yield
    finally:
        model.geom_group[gid] = group
