"""Differentiable view of a planar sign face: texture -> camera image by a homography.

Frames and conventions (as in `avsim.sensors.camera`)
- Texture: (3, H_tex, W_tex) float in [0, 1], row 0 at the top, as seen from the front.
  Unit-square texture coordinates (s, t): s to the right, t down, (0, 0) the outer
  top-left corner of texel (0, 0) and (1, 1) the outer bottom-right corner of the last
  texel, so s = 0..1 spans the texture's full width (grid_sample's align_corners=False).
- Image: pixel (u, v), u right, v down; pixel i covers [i, i + 1), so pixel centres are
  at i + 0.5 and the principal point of a W x H image is (W / 2, H / 2).
- Camera pose: position [m] and rotation whose columns are the MuJoCo camera axes
  (x right, y up, z backwards) in world coordinates (`CameraPose`).

The face is drawn by sampling the texture at the texture point behind every pixel
centre (`torch.nn.functional.grid_sample`, bilinear). Like OpenGL's trilinear mipmapping
(which MuJoCo's renderer uses), a far sign is sampled from a box-filtered copy of the
texture whose texels are about one pixel wide, so the warp low-passes the texture the
way the renderer does instead of aliasing it.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

# Unit-square texture coordinates of the four corners, in the order every corner
# array in this module uses: top-left, top-right, bottom-right, bottom-left.
UNIT_SQUARE_ST = ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0))


def project_points_px(points_world_m: torch.Tensor, cam_position_m: torch.Tensor, cam_rotation: torch.Tensor,
                      f_px: float | torch.Tensor, principal_point_px: tuple[float, float] | torch.Tensor
                      ) -> tuple[torch.Tensor, torch.Tensor]:
    """Pinhole projection of world points into B camera images.

    points_world_m: (B, N, 3) or (N, 3) world points [m].
    cam_position_m: (B, 3); cam_rotation: (B, 3, 3), columns = MuJoCo camera axes in the world.
    f_px: focal length [px], a float or (B,); principal_point_px: (cx, cy) or (B, 2).
    Returns (uv_px (B, N, 2) in continuous pixel coordinates, depth_m (B, N) along the
    optical axis). Points with depth <= 0 are behind the camera and their uv is meaningless.
    """
    if points_world_m.dim() == 2:
        points_world_m = points_world_m.expand(cam_position_m.shape[0], -1, -1)
    # Row vectors times R give R^T (p - c): the points in the MuJoCo camera frame.
    cam = torch.einsum("bnj,bjk->bnk", points_world_m - cam_position_m[:, None, :], cam_rotation)
    depth_m = -cam[..., 2]  # MuJoCo cameras look along their -z
    f = torch.as_tensor(f_px, dtype=cam.dtype).reshape(-1, 1)
    pp = torch.as_tensor(principal_point_px, dtype=cam.dtype).reshape(-1, 1, 2)
    u = pp[..., 0] + f * cam[..., 0] / depth_m
    v = pp[..., 1] - f * cam[..., 1] / depth_m  # camera y is up, image v is down
    return torch.stack([u, v], dim=-1), depth_m


def homography_from_corners(corners_px: torch.Tensor) -> torch.Tensor:
    """Homography (B, 3, 3) taking texture (s, t, 1) to image (u, v, 1) up to scale.

    corners_px: (B, 4, 2) image positions [px] of texture corners (s, t) = (0, 0), (1, 0),
    (1, 1), (0, 1). Closed-form square-to-quad map (Heckbert 1989, "Fundamentals of
    texture mapping and image warping", sec. 2.2.3), so it is differentiable in the corners
    and needs no linear solve. H is scaled so that its third output w = 1 at corner (0, 0);
    for a face wholly in front of the camera w is then > 0 over the whole square.
    """
    x0, x1, x2, x3 = corners_px[..., 0].unbind(-1)
    y0, y1, y2, y3 = corners_px[..., 1].unbind(-1)
    dx1, dx2, dx3 = x1 - x2, x3 - x2, x0 - x1 + x2 - x3
    dy1, dy2, dy3 = y1 - y2, y3 - y2, y0 - y1 + y2 - y3
    det = dx1 * dy2 - dx2 * dy1
    g = (dx3 * dy2 - dx2 * dy3) / det
    h = (dx1 * dy3 - dx3 * dy1) / det
    one = torch.ones_like(g)
    rows = [
        torch.stack([x1 - x0 + g * x1, x3 - x0 + h * x3, x0], -1),
        torch.stack([y1 - y0 + g * y1, y3 - y0 + h * y3, y0], -1),
        torch.stack([g, h, one], -1),
    ]
    return torch.stack(rows, dim=-2)


def texels_per_pixel(homography: torch.Tensor, texture_hw: tuple[int, int]) -> torch.Tensor:
    """Texture minification (B,) at the face centre: texels crossed per image pixel step.

    OpenGL's rho = max over the pixel x and y steps of the length of the step in texels;
    log2(rho) is the mip level it samples.
    """
    h_tex, w_tex = texture_hw
    inv = torch.linalg.inv(homography)
    centre = homography @ homography.new_tensor([0.5, 0.5, 1.0])
    p = torch.cat([centre[:, :2] / centre[:, 2:], torch.ones_like(centre[:, 2:])], dim=-1)  # (B, 3)
    q = torch.einsum("bij,bj->bi", inv, p)
    # d(s, t)/d(u, v) of s = q0 / q2, t = q1 / q2 with q = inv @ (u, v, 1).
    jac = (inv[:, :2, :2] * q[:, 2:, None] - q[:, :2, None] * inv[:, 2:, :2]) / q[:, 2:, None] ** 2
    scale = jac.new_tensor([w_tex, h_tex]).reshape(1, 2, 1)
    step_len = (jac * scale).norm(dim=1)  # (B, 2): texel length of a step along u and along v
    return step_len.max(dim=1).values


def _sampling_grid(homography: torch.Tensor, image_hw: tuple[int, int]) -> torch.Tensor:
    """grid_sample grid (B, H, W, 2) in [-1, 1] for every pixel centre; pixels whose ray
    meets the face plane behind the camera get a point far outside the texture."""
    height, width = image_hw
    inv = torch.linalg.inv(homography)
    v, u = torch.meshgrid(torch.arange(height, dtype=inv.dtype) + 0.5, torch.arange(width, dtype=inv.dtype) + 0.5, indexing="ij")
    pix = torch.stack([u, v, torch.ones_like(u)], dim=-1)  # (H, W, 3)
    q = torch.einsum("bij,hwj->bhwi", inv, pix)
    w = q[..., 2:]
    in_front = w > 0
    st = q[..., :2] / torch.where(in_front, w, torch.ones_like(w))
    return torch.where(in_front, 2 * st - 1, torch.full_like(st, -4.0))


def _mip_pyramid(rgba: torch.Tensor, n_levels: int) -> list[torch.Tensor]:
    """Box-filtered halvings of (T, 4, H_tex, W_tex), as glGenerateMipmap builds them."""
    levels = [rgba]
    for _ in range(n_levels - 1):
        levels.append(F.avg_pool2d(levels[-1], 2))
    return levels


def warp_texture(texture: torch.Tensor, alpha: torch.Tensor, corners_px: torch.Tensor, image_hw: tuple[int, int],
                 mipmap: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """Draw the texture square into B camera images.

    texture: (3, H_tex, W_tex) or (B, 3, H_tex, W_tex), float in [0, 1].
    alpha: (1, H_tex, W_tex) in [0, 1], 1 on the sign face (e.g. inside the octagon).
    corners_px: (B, 4, 2) image positions [px] of the texture corners in `UNIT_SQUARE_ST`
      order; the face must be in front of the camera (all corner depths > 0).
    image_hw: (H, W) of the camera image [px].
    mipmap: sample a box-filtered level of about one texel per pixel, blending the two
      nearest levels as OpenGL's GL_LINEAR_MIPMAP_LINEAR does; False samples the full texture.
    Returns (warped (B, 3, H, W), mask (B, 1, H, W)): the face colour behind each pixel and
    the fraction of the pixel the face covers (0 off the face and outside the square).
    Differentiable in `texture` and `corners_px`.
    """
    batch = corners_px.shape[0]
    textures = texture if texture.dim() == 4 else texture[None]
    h_tex, w_tex = textures.shape[-2:]
    # Premultiplied alpha: texels outside the face (the grey square corners) carry no colour,
    # so bilinear and box filtering at the outline blend face colour with coverage only.
    rgba = torch.cat([textures * alpha, alpha.expand(textures.shape[0], -1, -1, -1)], dim=1)
    homography = homography_from_corners(corners_px.double())
    grid = _sampling_grid(homography, image_hw).to(textures.dtype)

    n_levels = int(math.log2(min(h_tex, w_tex))) + 1 if mipmap else 1
    pyramid = _mip_pyramid(rgba, n_levels)
    lod = torch.log2(texels_per_pixel(homography, (h_tex, w_tex)).detach()).clamp(0, n_levels - 1)
    lower = lod.floor().long().clamp(max=n_levels - 2) if n_levels > 1 else torch.zeros(batch, dtype=torch.long)
    frac = (lod - lower).to(textures.dtype)

    out = torch.zeros(batch, 4, *image_hw, dtype=textures.dtype)
    for level in lower.unique().tolist():
        idx = (lower == level).nonzero().squeeze(1)

        def sample(lv: int) -> torch.Tensor:
            src = pyramid[lv]
            src = src[idx] if src.shape[0] > 1 else src.expand(len(idx), -1, -1, -1)
            return F.grid_sample(src, grid[idx], mode="bilinear", padding_mode="zeros", align_corners=False)

        if n_levels == 1:
            out[idx] = sample(0)
        else:
            f = frac[idx].reshape(-1, 1, 1, 1)
            out[idx] = (1 - f) * sample(level) + f * sample(level + 1)

    mask = out[:, 3:].clamp(0, 1)
    warped = out[:, :3] / out[:, 3:].clamp_min(1e-6)  # un-premultiply; 0 where the mask is 0
    return warped.clamp(0, 1), mask


def fit_gain_offset(warped: torch.Tensor, mask: torch.Tensor, rendered: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-channel lighting of the face: `rendered ~ gain * warped + offset` by weighted least squares.

    warped: (B, 3, H, W) the clean texture warped into each view; mask: (B, 1, H, W) weights
    (pass an eroded or thresholded coverage mask so edge pixels, which mix in the background,
    do not bias the fit); rendered: (B, 3, H, W) MuJoCo's render with that clean texture, in [0, 1].
    Returns (gain (B, 3), offset (B, 3)). The fit is a calibration of the renderer's lights,
    not part of an attack's graph, so it is computed without gradients.
    """
    with torch.no_grad():
        w = mask.expand_as(warped)
        total = w.sum(dim=(2, 3)).clamp_min(1e-9)
        mean_x = (w * warped).sum(dim=(2, 3)) / total
        mean_y = (w * rendered).sum(dim=(2, 3)) / total
        dx = warped - mean_x[..., None, None]
        dy = rendered - mean_y[..., None, None]
        var = (w * dx * dx).sum(dim=(2, 3))
        cov = (w * dx * dy).sum(dim=(2, 3))
        gain = cov / var.clamp_min(1e-9)  # a flat channel (var = 0) gets gain 0 and its mean as offset
        return gain, mean_y - gain * mean_x


def composite(warped: torch.Tensor, mask: torch.Tensor, background: torch.Tensor,
              gain: torch.Tensor, offset: torch.Tensor) -> torch.Tensor:
    """Camera image with the face drawn in: mask * (gain * warped + offset) + (1 - mask) * background.

    warped (B, 3, H, W), mask (B, 1, H, W), background (B, 3, H, W) or (3, H, W) in [0, 1];
    gain, offset (B, 3). The lit face is clamped to [0, 1] because the renderer saturates there.
    Returns (B, 3, H, W).
    """
    lit = (gain[..., None, None] * warped + offset[..., None, None]).clamp(0, 1)
    return mask * lit + (1 - mask) * background
