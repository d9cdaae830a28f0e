"""A bank of real MuJoCo camera views of the stop sign, for expectation over transformation.

Each view is a crop of a rendered camera frame around the stop sign, with the sign's face
hidden (the background the attacked face is drawn over), the face's texture corners in the
crop [px], and the per-channel gain and offset that map the texture to the renderer's
lighting (fitted on the clean texture). Views come in groups: one town, placement, sun and
fog, seen at a series of distances, so a group read in order is a drive-by sequence.

Crops keep the optimisation cheap (a 256x256 crop costs about a fifth of a 640x480 frame);
the detector is fully convolutional, so its cells around the sign see the same pixels
apart from context beyond the crop. Every attack is then judged on full MuJoCo frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from avsim.attacks.sign_view import corners_px, face_alpha, face_hidden, sign_view
from avsim.attacks.warp import fit_gain_offset, warp_texture
from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.sensors.camera import CAMERA_NAMES
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import PLACEMENTS, TOWNS

CROP_PX = 256  # a multiple of the detector's largest stride (32)


@dataclass(frozen=True)
class ViewBankSpec:
    """What the bank samples. Distances are camera-independent: front bumper to the sign [m].

    cameras: the car cameras whose views go into the bank, each seeing the same drive-by
    distances. ("front", "side") is the adaptive attacker's bank: the side camera (yawed
    towards the roadside) keeps the whole stop sign in frame from 10 m to beyond 60 m, so
    the default range gives it about as many views as the front camera.
    """

    towns: tuple[str, ...] = ("town03", "town07", "town10")
    placements: tuple[str, ...] = ("near", "standard", "far")
    cameras: tuple[str, ...] = ("front",)
    lightings_per_cell: int = 2
    views_per_group: int = 12
    dist_range_m: tuple[float, float] = (10.0, 60.0)
    lateral_jitter_m: float = 0.5  # car position across its lane
    yaw_jitter_deg: float = 2.0  # car heading, so the sign is seen slightly off-axis
    fog_probability: float = 0.3
    seed: int = 0

    def __post_init__(self) -> None:
        # Checked here, before any rendering, so a misspelt camera costs nothing.
        unknown = [c for c in self.cameras if c not in CAMERA_NAMES]
        if not self.cameras or unknown or len(set(self.cameras)) != len(self.cameras):
            raise ConfigError(f"view bank cameras must be distinct names from {', '.join(CAMERA_NAMES)}; "
                              f"got {','.join(self.cameras) or 'none'}")


@dataclass
class ViewBank:
    """N views. Tensors: backgrounds (N, 3, S, S) uint8, corners_px (N, 4, 2) in crop pixels,
    gain and offset (N, 3), sign_box_px (N, 4) xyxy in crop pixels; per view its group index,
    camera name and bumper-to-sign distance [m]. Groups are lists of view indices sorted by
    decreasing distance (the order a car meets them)."""

    backgrounds: torch.Tensor
    corners_px: torch.Tensor
    gain: torch.Tensor
    offset: torch.Tensor
    sign_box_px: torch.Tensor
    group: list[int]
    camera: list[str]
    dist_m: list[float]
    groups: list[list[int]]
    alpha: torch.Tensor  # (1, H_tex, W_tex) the face outline on the texture square

    def __len__(self) -> int:
        return len(self.camera)


def _lighting(rng: np.random.Generator, fog_probability: float) -> dict[str, float]:
    fog = rng.random() < fog_probability
    return {"sun_elevation_deg": float(rng.uniform(20, 75)), "sun_azimuth_deg": float(rng.uniform(-180, 180)),
            "sun_intensity": float(rng.uniform(0.6, 1.3)),
            "fog_start_m": float(rng.uniform(0, 20)) if fog else 0.0, "fog_end_m": float(rng.uniform(120, 300)) if fog else 0.0}


def _crop_origin(centre_px: np.ndarray, width_px: int, height_px: int) -> tuple[int, int]:
    x0 = int(np.clip(round(centre_px[0] - CROP_PX / 2), 0, width_px - CROP_PX))
    y0 = int(np.clip(round(centre_px[1] - CROP_PX / 2), 0, height_px - CROP_PX))
    return x0, y0


def build_view_bank(spec: ViewBankSpec, clean_texture: torch.Tensor, base: SimConfig | None = None) -> ViewBank:
    """Render the bank. clean_texture: (3, H_tex, W_tex) in [0, 1], the texture the gains are fitted on."""
    for town in spec.towns:
        TOWNS.get(town)
    for placement in spec.placements:
        PLACEMENTS.get(placement)
    rng = np.random.default_rng(spec.seed)
    base = base or SimConfig()
    alpha = None
    backgrounds, corners, gains, offsets, boxes = [], [], [], [], []
    group_of, camera_of, dist_of, groups = [], [], [], []
    for town in spec.towns:
        for placement in spec.placements:
            for _ in range(spec.lightings_per_cell):
                scenario = {"town": town, "placement": placement, **_lighting(rng, spec.fog_probability)}
                config = with_overrides(base, {"scenario": scenario, "perception": {"kind": "oracle"}})
                loop = ClosedLoop(config)
                try:
                    sign = loop.scene.stop_sign
                    if alpha is None:
                        alpha = face_alpha(sign.shape, *clean_texture.shape[-2:])
                    lo, hi = spec.dist_range_m
                    edges = np.linspace(hi, lo, spec.views_per_group + 1)
                    dists = edges[:-1] + (edges[1:] - edges[:-1]) * rng.random(spec.views_per_group)
                    for camera in spec.cameras:
                        members = []
                        for dist_m in dists:
                            bumper_x = sign.base_pos_m[0] - dist_m
                            y = loop.scene.layout.lane_center_y_m + rng.uniform(-1, 1) * spec.lateral_jitter_m
                            yaw = np.radians(rng.uniform(-1, 1) * spec.yaw_jitter_deg)
                            loop.vehicle.place(bumper_x - FRONT_BUMPER_X_M, y, yaw, 0.0)
                            view = sign_view(loop.rig, loop.data, camera, sign)
                            try:
                                uv = corners_px([view])[0].numpy()
                            except ValueError:
                                continue  # sign behind this camera
                            width, height = view.intrinsics.width_px, view.intrinsics.height_px
                            if uv[:, 0].max() < 0 or uv[:, 0].min() > width or uv[:, 1].max() < 0 or uv[:, 1].min() > height:
                                continue  # out of view: no loss from it (it would reward nothing)
                            x0, y0 = _crop_origin(uv.mean(axis=0), width, height)
                            rendered = loop.rig.render_rgb(loop.data, camera)[y0:y0 + CROP_PX, x0:x0 + CROP_PX]
                            with face_hidden(loop.model, sign):
                                background = loop.rig.render_rgb(loop.data, camera)[y0:y0 + CROP_PX, x0:x0 + CROP_PX]
                            uv_crop = torch.as_tensor(uv - (x0, y0), dtype=torch.float32)[None]
                            warped, mask = warp_texture(clean_texture, alpha, uv_crop, (CROP_PX, CROP_PX))
                            solid = (mask > 0.99).float()
                            if solid.sum() < 12:
                                continue  # too few whole face pixels to fit the lighting
                            target = torch.from_numpy(rendered).permute(2, 0, 1)[None].float() / 255
                            gain, offset = fit_gain_offset(warped, solid, target)
                            box = torch.cat([uv_crop[0].min(dim=0).values, uv_crop[0].max(dim=0).values])
                            members.append(len(camera_of))
                            backgrounds.append(torch.from_numpy(background.copy()).permute(2, 0, 1))
                            corners.append(uv_crop[0])
                            gains.append(gain[0])
                            offsets.append(offset[0])
                            boxes.append(box)
                            group_of.append(len(groups))
                            camera_of.append(camera)
                            dist_of.append(float(dist_m))
                        if members:
                            groups.append(members)
                finally:
                    loop.close()
    if not camera_of:
        raise ValueError("no view of the stop sign could be rendered; check the distance range and cameras")
    return ViewBank(torch.stack(backgrounds), torch.stack(corners), torch.stack(gains), torch.stack(offsets),
                    torch.stack(boxes), group_of, camera_of, dist_of, groups, alpha)
