"""The differentiable sign warp against MuJoCo's own render of the stop sign (town07, standard)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import pytest
import torch

from avsim.attacks.sign_view import SignView, corners_px, face_alpha, face_hidden, sign_view, texture_corners_m
from avsim.attacks.warp import (UNIT_SQUARE_ST, composite, fit_gain_offset, homography_from_corners,
                                project_points_px, warp_texture)
from avsim.loop import ClosedLoop
from avsim.world.signs import SIGN_SHAPES
from avsim.world.textures import CLEAN_TEXTURE_FILES, TEXTURE_DIR, load_texture_png
from helpers import make_config

# Mean |composite - render| per channel inside the eroded face, on a 0..1 scale. The warp
# measures about 0.3/255 at 20-30 m; misregistering it by half a pixel already costs
# 6-10/255, a 3 px shift or a mirrored texture 15-30/255.
PHOTOMETRIC_TOL = 3.0 / 255
CLEAN_SHAPE = SIGN_SHAPES["stop_sign"]


@pytest.fixture(scope="module")
def town07():
    loop = ClosedLoop(make_config(scenario={"town": "town07", "placement": "standard"}))
    yield loop
    loop.close()


@pytest.fixture(scope="module")
def clean_texture() -> torch.Tensor:
    rgb = load_texture_png(TEXTURE_DIR / CLEAN_TEXTURE_FILES["stop_sign"])
    return torch.from_numpy(rgb).permute(2, 0, 1).float() / 255.0


@dataclass(frozen=True)
class Shot:
    """One front-camera frame: the geometry, the render (1, 3, H, W) and the render with the face hidden."""

    view: SignView
    rendered: torch.Tensor
    background: torch.Tensor


def _place_camera(loop: ClosedLoop, depth_m: float) -> None:
    """Car in its lane, at rest, with the sign face `depth_m` ahead of the front camera along the road."""
    cam_x = float(loop.model.cam_pos[loop.model.camera("car/front").id][0])
    loop.vehicle.place(loop.scene.stop_sign.face_center_m[0] - depth_m - cam_x, loop.scene.layout.lane_center_y_m, 0.0, 0.0)


def _as_tensor(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(image).permute(2, 0, 1).float()[None] / 255.0


def _shot(loop: ClosedLoop, depth_m: float) -> Shot:
    _place_camera(loop, depth_m)
    sign = loop.scene.stop_sign
    rendered = _as_tensor(loop.rig.render_rgb(loop.data, "front"))
    with face_hidden(loop.model, sign):
        background = _as_tensor(loop.rig.render_rgb(loop.data, "front"))
    return Shot(sign_view(loop.rig, loop.data, "front", sign), rendered, background)


def _face_core(mask: torch.Tensor) -> torch.Tensor:
    """Pixels (B, 1, H, W) wholly on the face, eroded by one more pixel: MuJoCo draws the
    outline aliased (no multisampling), so the outline's pixels are left out of the check."""
    full = (mask[:, 0] > 0.999).numpy().astype(np.uint8)
    core = np.stack([cv2.erode(m, np.ones((3, 3), np.uint8)) for m in full])
    return torch.from_numpy(core).float()[:, None]


def _photometric_error(shot: Shot, texture: torch.Tensor, corners: torch.Tensor, core: torch.Tensor) -> float:
    """Mean |composite - render| inside `core`, with gain/offset fitted to this warp in `core`."""
    alpha = face_alpha(CLEAN_SHAPE, *texture.shape[-2:])
    warped, mask = warp_texture(texture, alpha, corners, shot.view.image_hw)
    gain, offset = fit_gain_offset(warped, core, shot.rendered)
    image = composite(warped, mask, shot.background, gain, offset)
    diff = (image - shot.rendered).abs().mean(dim=1, keepdim=True)
    return float((diff * core).sum() / core.sum())


@pytest.mark.parametrize("depth_m", [20.0, 30.0])
def test_warp_matches_the_mujoco_render_inside_the_face(town07, clean_texture, depth_m):
    shot = _shot(town07, depth_m)
    corners = corners_px([shot.view])
    _, mask = warp_texture(clean_texture, face_alpha(CLEAN_SHAPE, *clean_texture.shape[-2:]), corners, shot.view.image_hw)
    core = _face_core(mask)
    assert core.sum() > 150  # a 20-30 m sign is 23-34 px tall: hundreds of pixels to compare
    assert _photometric_error(shot, clean_texture, corners, core) < PHOTOMETRIC_TOL


def test_mirrored_texture_or_shifted_corners_fail_the_photometric_check(town07, clean_texture):
    shot = _shot(town07, 25.0)
    corners = corners_px([shot.view])
    _, mask = warp_texture(clean_texture, face_alpha(CLEAN_SHAPE, *clean_texture.shape[-2:]), corners, shot.view.image_hw)
    core = _face_core(mask)  # always judged on the true face, so a shifted warp is caught
    assert _photometric_error(shot, clean_texture, corners, core) < PHOTOMETRIC_TOL
    assert _photometric_error(shot, clean_texture.flip(-1), corners, core) > 3 * PHOTOMETRIC_TOL
    for shift_px in ([3.0, 0.0], [0.0, 3.0], [-3.0, 0.0]):
        shifted = corners + torch.tensor(shift_px, dtype=corners.dtype)
        assert _photometric_error(shot, clean_texture, shifted, core) > 3 * PHOTOMETRIC_TOL


def test_gradients_reach_the_face_texels_and_only_them(town07, clean_texture):
    shot = _shot(town07, 25.0)
    texture = clean_texture.clone().requires_grad_(True)
    alpha = face_alpha(CLEAN_SHAPE, *texture.shape[-2:])
    warped, mask = warp_texture(texture, alpha, corners_px([shot.view]), shot.view.image_hw)
    gain, offset = fit_gain_offset(warped, _face_core(mask), shot.rendered)
    # The darker the sign, the lower the loss: every face texel should feel it.
    composite(warped, mask, shot.background, gain, offset).sum().backward()
    grad = texture.grad.abs().sum(dim=0)
    assert torch.isfinite(texture.grad).all()
    assert (grad[alpha[0] > 0.5] > 0).float().mean() > 0.99
    assert (grad[alpha[0] == 0] == 0).all()  # the grey corners outside the octagon never show


def test_warp_gradient_matches_finite_differences():
    torch.manual_seed(0)
    texture = torch.rand(3, 8, 8, dtype=torch.float64, requires_grad=True)
    alpha = torch.ones(1, 8, 8, dtype=torch.float64)
    corners = torch.tensor([[[3.2, 2.7], [12.1, 3.4], [11.6, 13.0], [2.5, 12.2]]], dtype=torch.float64)

    def warped(tex: torch.Tensor) -> torch.Tensor:  # kept off the [0, 1] clamp, where the map has kinks
        return warp_texture(0.25 + 0.5 * tex, alpha, corners, (16, 16))[0]

    assert torch.autograd.gradcheck(warped, (texture,), eps=1e-6, atol=1e-5, fast_mode=True)


def test_homography_takes_the_unit_square_to_the_corners():
    corners = torch.tensor([[[100.0, 50.0], [180.0, 60.0], [170.0, 140.0], [95.0, 120.0]]], dtype=torch.float64)
    h = homography_from_corners(corners)[0]
    st1 = torch.cat([torch.tensor(UNIT_SQUARE_ST, dtype=torch.float64), torch.ones(4, 1, dtype=torch.float64)], dim=1)
    uvw = st1 @ h.T
    assert (uvw[:, 2] > 0).all()
    assert torch.allclose(uvw[:, :2] / uvw[:, 2:], corners[0], atol=1e-9)


def test_projection_agrees_with_opencv(town07):
    _place_camera(town07, 25.0)
    view = sign_view(town07.rig, town07.data, "front", town07.scene.stop_sign)
    rvec, tvec = view.pose.opencv_extrinsics()
    expected, _ = cv2.projectPoints(view.texture_corners_m, rvec, tvec, view.intrinsics.matrix(), None)
    assert np.allclose(corners_px([view])[0].numpy(), expected.reshape(4, 2), atol=1e-6)
    _, depth_m = project_points_px(torch.as_tensor(view.texture_corners_m), torch.as_tensor(view.pose.position_m)[None],
                                   torch.as_tensor(view.pose.rotation)[None], view.intrinsics.f_px,
                                   view.intrinsics.principal_point_px)
    assert np.allclose(depth_m[0].numpy(), view.corner_depths_m())


def test_texture_square_bounds_the_compiled_face_mesh(town07):
    """The corners are derived from signs.py's UV mapping; the compiled mesh must agree."""
    sign = town07.scene.stop_sign
    gid = town07.model.geom(sign.face_geom).id
    mesh = town07.model.geom_dataid[gid]
    start, count = town07.model.mesh_vertadr[mesh], town07.model.mesh_vertnum[mesh]
    local = town07.model.mesh_vert[start: start + count]
    world = local @ town07.data.geom_xmat[gid].reshape(3, 3).T + town07.data.geom_xpos[gid]
    front = world[np.isclose(world[:, 0], world[:, 0].min(), atol=1e-4)]  # the textured cap faces -x
    corners = texture_corners_m(sign)
    assert np.allclose(corners[:, 0], front[0, 0], atol=1e-5)
    assert np.allclose([front[:, 1].max(), front[:, 2].max()], corners[0, 1:], atol=1e-5)  # top-left, seen from the front
    assert np.allclose([front[:, 1].min(), front[:, 2].min()], corners[2, 1:], atol=1e-5)  # bottom-right


def test_batched_views_match_single_views(town07, clean_texture):
    views = []
    for depth_m in (20.0, 45.0):  # different mip levels in one batch
        _place_camera(town07, depth_m)
        views.append(sign_view(town07.rig, town07.data, "front", town07.scene.stop_sign))
    alpha = face_alpha(CLEAN_SHAPE, *clean_texture.shape[-2:])
    warped, mask = warp_texture(clean_texture, alpha, corners_px(views), views[0].image_hw)
    for k, view in enumerate(views):
        alone, alone_mask = warp_texture(clean_texture, alpha, corners_px([view]), view.image_hw)
        assert torch.allclose(warped[k], alone[0]) and torch.allclose(mask[k], alone_mask[0])


def test_face_hidden_hides_only_inside_the_block(town07):
    sign = town07.scene.stop_sign
    gid = town07.model.geom(sign.face_geom).id
    group = int(town07.model.geom_group[gid])
    shot = _shot(town07, 25.0)
    assert int(town07.model.geom_group[gid]) == group
    _, mask = warp_texture(torch.zeros(3, 64, 64), face_alpha(CLEAN_SHAPE, 64, 64), corners_px([shot.view]), shot.view.image_hw)
    core = _face_core(mask)

    def redness(image: torch.Tensor) -> float:  # mean of R - (G + B) / 2 over the face
        excess = image[:, :1] - image[:, 1:].mean(dim=1, keepdim=True)
        return float((excess * core).sum() / core.sum())

    assert redness(shot.rendered) > 0.3 and redness(shot.background) < 0.1
