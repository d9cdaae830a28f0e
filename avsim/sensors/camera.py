"""Car cameras rendered offscreen with `mujoco.Renderer`.

Conventions
- Image: pixel (u, v) with u to the right, v down; pixel i covers [i, i + 1), so the
  principal point of a W x H image is (W / 2, H / 2). Boxes are (x0, y0, x1, y1) in
  these continuous pixel coordinates.
- MuJoCo camera frame: looks along -z, y up. OpenCV camera frame (used for
  `cv2.projectPoints`): x right, y down, z forward = MuJoCo (x, -y, -z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.config import CameraConfig, focal_length_px
from avsim.sensors.gl import OffscreenRenderer
from avsim.sensors.noise import SensorNoise
from avsim.sensors.photo import PhotoModel

CAMERA_NAMES = ("front", "side")
# The ego car's own shell is in geom group 2; its cameras do not see it (they sit inside it).
EGO_GROUP = 2
# How many segmentation pixel rows a sign's box can span beyond its outline's projected height h: the rows whose
# centres lie within a span of h number at most floor(h) + 1 (1 row), and the outline's points leave out the face's
# thickness and GL's own rounding, for which the region read back is padded by 2 px (2 rows). A sign that cannot
# reach the height a caller asks for (`CameraRig.sign_boxes`' min_height_px) is so left out only where its box
# would be shorter: the oracle's frames of a far sign render nothing and detect what they did.
SMALLEST_BOX_SLACK_SEG_PX = 3.0


def camera_view_option() -> mujoco.MjvOption:
    """What the car's cameras draw: every geom group but the ego shell's and group 3 (the hidden
    physical road plane, `avsim.world.props`)."""
    option = mujoco.MjvOption()
    option.geomgroup[EGO_GROUP] = 0
    option.geomgroup[3] = 0
    return option


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of a camera with square pixels and a centred principal point."""

    width_px: int
    height_px: int
    fovy_deg: float

    @property
    def f_px(self) -> float:
        """Focal length [px] = (H / 2) / tan(fovy / 2)."""
        return focal_length_px(self.height_px, self.fovy_deg)

    @property
    def principal_point_px(self) -> tuple[float, float]:
        """(cx, cy) [px]: the image centre, in continuous pixel coordinates."""
        return self.width_px / 2, self.height_px / 2

    def matrix(self) -> np.ndarray:
        """3x3 camera matrix K."""
        cx, cy = self.principal_point_px
        return np.array([[self.f_px, 0.0, cx], [0.0, self.f_px, cy], [0.0, 0.0, 1.0]])

    @property
    def fovx_deg(self) -> float:
        """Horizontal field of view [deg], from the width and the focal length (MuJoCo's fovy is vertical)."""
        return math.degrees(2 * math.atan(self.width_px / 2 / self.f_px))


def intrinsics_for(camera: str, config: CameraConfig) -> Intrinsics:
    """The intrinsics of camera "front" or "side" under `config` (the side camera has its own fovy)."""
    fovy = config.fovy_deg if camera == "front" else config.side_fovy_deg
    return Intrinsics(config.width_px, config.height_px, fovy)


@dataclass(frozen=True)
class CameraPose:
    """Camera pose in the world: position [m] and rotation whose columns are the
    MuJoCo camera axes (x right, y up, z backwards) in world coordinates."""

    position_m: np.ndarray  # (3,)
    rotation: np.ndarray  # (3, 3)

    def opencv_extrinsics(self) -> tuple[np.ndarray, np.ndarray]:
        """(rvec, tvec) mapping world points into the OpenCV camera frame."""
        import cv2

        r_world_from_cv = self.rotation @ np.diag([1.0, -1.0, -1.0])
        r_cv_from_world = r_world_from_cv.T
        rvec, _ = cv2.Rodrigues(r_cv_from_world)
        return rvec, -r_cv_from_world @ self.position_m

    def depth_m(self, point_world_m: np.ndarray) -> float:
        """Depth of a world point along the optical axis [m] (the pinhole model's Z)."""
        return float(-(self.rotation[:, 2] @ (np.asarray(point_world_m) - self.position_m)))


def render_key(model: mujoco.MjModel, data: mujoco.MjData) -> bytes:
    """What a frame is drawn from: the time, the joint and mocap positions, every geom's, camera's and
    light's pose, and every geom's group and colour (which hide or tint it). The rest of the model
    does not change during a run."""
    return b"".join(np.ascontiguousarray(a).tobytes() for a in (
        np.float64(data.time), data.qpos, data.mocap_pos, data.mocap_quat, data.geom_xpos, data.geom_xmat,
        data.cam_xpos, data.cam_xmat, data.light_xpos, data.light_xdir, model.geom_group, model.geom_rgba))


class CameraRig:
    """Renders the car's cameras. One RGB and one segmentation renderer serve both
    cameras (a renderer is not tied to a camera), created on first use so that a
    run that needs no RGB never pays for it."""

    def __init__(self, model: mujoco.MjModel, config: CameraConfig, camera_prefix: str = "car/", fog: bool = False) -> None:
        self._model = model
        self._fog = fog
        self._config = config
        self._ids = {name: model.camera(camera_prefix + name).id for name in CAMERA_NAMES}
        self._rgb: OffscreenRenderer | None = None
        self._seg: OffscreenRenderer | None = None
        self._option = camera_view_option()
        self.reuse_last_frame = False  # see `render_rgb`
        self._last_rgb: dict[str, tuple[bytes, np.ndarray]] = {}  # camera -> (state, frame): `render_rgb`
        self._photo = PhotoModel.from_config(config)

    def pool_kept_frames(self, other: CameraRig) -> None:
        """Keep last frames (`reuse_last_frame`) in one store with `other`. For the rigs of sibling runs
        (`avsim.frame_sharing`), whose models draw the same frame from the same state: each kept frame
        is keyed by the state it was drawn from, so a rig finds another's frame only where it would
        draw that frame itself (a recorder's render of a state its sibling's recorder drew)."""
        self._last_rgb = other._last_rgb

    @property
    def config(self) -> CameraConfig:
        """The cameras' config: resolution, fields of view and the photographic stages."""
        return self._config

    def intrinsics(self, camera: str) -> Intrinsics:
        """The intrinsics of `camera` ("front" or "side")."""
        return intrinsics_for(camera, self._config)

    def pose(self, data: mujoco.MjData, camera: str) -> CameraPose:
        """`camera`'s pose in the world at the state `data` holds (MuJoCo camera axes, see `CameraPose`)."""
        cid = self._ids[camera]
        return CameraPose(data.cam_xpos[cid].copy(), data.cam_xmat[cid].reshape(3, 3).copy())

    def render_rgb(self, data: mujoco.MjData, camera: str, region_px: tuple[int, int, int, int] | None = None,
                   noise: SensorNoise | None = None) -> np.ndarray:
        """RGB image (H, W, 3) uint8, row 0 at the top (a fresh array), through the camera's
        photographic model (`avsim.sensors.photo`: lens, photosite, then `noise`, then the ISP's
        encoding; all off by default).

        region_px: (x0, y0, x1, y1) [px], end-exclusive: read back only that part (the same pixels
        as in the whole image; reading back is where a software rasteriser spends its time) and
        leave the rest zero. For a perception that looks at a region of interest only.

        noise: the run's sensor noise, drawn for this frame (None: none). It is added after the
        lens and the photosite and before the JPEG encoding, as in a camera.

        With `reuse_last_frame` on, the last frame of each camera is kept with what it was drawn
        from (the poses, and the geoms' groups and colours), and asking again for the same camera
        and state returns a copy of it instead of drawing it again: in a recorded run a recorder
        and the perception both ask for each sensing state's frame. It is off by default, because
        a caller may change the model's appearance in other ways between two renders of one state
        (a texture, a light); the recorders turn it on for their run, in which nothing does. Then
        every frame is drawn whole, a region included, since the recorder wants the whole of it.
        The kept frame is the one before the noise and the encoding.
        """
        width, height = self._config.width_px, self._config.height_px
        padded = self._photo.padded_region(region_px, width, height)
        key = render_key(self._model, data) if self.reuse_last_frame else None
        last = self._last_rgb.get(camera)
        if key is not None and last is not None and last[0] == key:
            frame = last[1].copy()
        else:
            frame = self._draw(data, camera, padded if key is None else None)
            if key is not None:
                self._last_rgb[camera] = (key, frame.copy())
        if noise is not None:
            frame = noise.apply(frame, padded)
        if self._photo.jpeg_quality:
            if padded is None:
                frame = self._photo.encode(frame)
            else:
                x0, y0, x1, y1 = padded
                frame[y0:y1, x0:x1] = self._photo.encode(frame[y0:y1, x0:x1])
        if padded != region_px:  # keep the region asked for only, as a region render always has
            x0, y0, x1, y1 = region_px
            kept = np.zeros_like(frame)
            kept[y0:y1, x0:x1] = frame[y0:y1, x0:x1]
            frame = kept
        return frame

    def _draw(self, data: mujoco.MjData, camera: str, region_px: tuple[int, int, int, int] | None) -> np.ndarray:
        """A fresh (H, W, 3) frame through the lens and the photosites: whole, or only `region_px`
        (the rest zero)."""
        s = self._photo.supersample
        if self._rgb is None:
            self._rgb = OffscreenRenderer(self._model, self._config.width_px * s, self._config.height_px * s,
                                          segmentation=False, fog=self._fog, texture_anisotropy=self._config.texture_anisotropy)
        if region_px is None:
            return np.array(self._photo.lens(self._photo.integrate(self._rgb.render(data, self._ids[camera], self._option))))
        x0, y0, x1, y1 = region_px
        frame = np.zeros((self._config.height_px, self._config.width_px, 3), np.uint8)
        rendered = self._rgb.render(data, self._ids[camera], self._option, (x0 * s, y0 * s, x1 * s, y1 * s))
        frame[y0:y1, x0:x1] = self._photo.lens(self._photo.integrate(rendered))
        return frame

    def render_segmentation(self, data: mujoco.MjData, camera: str) -> np.ndarray:
        """Model geom id per pixel, (H * s, W * s) int32 with s = seg_supersample; -1 for background."""
        if self._seg is None:
            ss = self._config.seg_supersample
            self._seg = OffscreenRenderer(self._model, self._config.width_px * ss, self._config.height_px * ss, segmentation=True)
        colours = self._seg.render(data, self._ids[camera], self._option).astype(np.int32)
        packed = colours[..., 0] | (colours[..., 1] << 8) | (colours[..., 2] << 16)
        return self._seg.geom_id_lookup()[packed]

    def sign_boxes(self, data: mujoco.MjData, camera: str, signs: dict[str, tuple[int, np.ndarray]],
                   min_height_px: float = 0.0) -> dict[str, tuple[float, float, float, float]]:
        """Tight box of each sign face's visible pixels, from a segmentation render.

        signs: name -> (face geom id, (N, 3) world points enclosing the face). The points
        only bound the part of the image read back; the box comes from the segmentation
        pixels, so occluded parts of a sign are left out of it.
        min_height_px: the caller wants no box shorter than this [image px]. A sign whose projected
        outline cannot cover that many pixel rows is left out before rendering, and with none left
        nothing is rendered: the oracle's far frames (`SMALLEST_BOX_SLACK_SEG_PX` says why this
        drops only boxes the caller would drop). 0: every visible sign.
        Returns name -> (x0, y0, x1, y1) in RGB-image pixel coordinates, with edges at
        multiples of 1 / seg_supersample px; signs with no visible pixel are left out.
        """
        ss = self._config.seg_supersample
        width, height = self._config.width_px * ss, self._config.height_px * ss
        pose = self.pose(data, camera)
        regions = {name: self._project_bounds(pose, camera, pts, ss, min_height_px) for name, (_, pts) in signs.items()}
        regions = {name: r for name, r in regions.items() if r is not None}
        if not regions:
            return {}
        x0 = min(r[0] for r in regions.values())
        y0 = min(r[1] for r in regions.values())
        x1 = max(r[2] for r in regions.values())
        y1 = max(r[3] for r in regions.values())
        if self._seg is None:
            self._seg = OffscreenRenderer(self._model, width, height, segmentation=True)
        colours = self._seg.render(data, self._ids[camera], self._option, (x0, y0, x1, y1))
        values = self._seg.segment_ids_of([signs[name][0] for name in regions])
        one_channel = self._seg.scene_geom_count < 0xFF
        boxes = {}
        for name, value in zip(regions, values):
            if value == 0:
                continue
            mask = colours[..., 0] == (value & 0xFF)
            if not one_channel:  # ids above 255 spill into G and B
                mask &= (colours[..., 1] == ((value >> 8) & 0xFF)) & (colours[..., 2] == (value >> 16))
            rows = np.flatnonzero(mask.any(axis=1))
            if rows.size == 0:
                continue
            cols = np.flatnonzero(mask[rows[0]: rows[-1] + 1].any(axis=0))
            boxes[name] = ((x0 + cols[0]) / ss, (y0 + rows[0]) / ss, (x0 + cols[-1] + 1) / ss, (y0 + rows[-1] + 1) / ss)
        return boxes

    def _project_bounds(self, pose: CameraPose, camera: str, points_m: np.ndarray, ss: int,
                        min_height_px: float = 0.0) -> tuple[int, int, int, int] | None:
        """Pixel rectangle (x0, y0, x1, y1) at seg resolution enclosing the projected points,
        padded by 2 px and clipped to the image; None if entirely outside the view, or if the points,
        wholly in front of the camera, project shorter than `min_height_px` [image px] with
        `SMALLEST_BOX_SLACK_SEG_PX` (no box of theirs could be that tall)."""
        width, height = self._config.width_px * ss, self._config.height_px * ss
        cam = (np.asarray(points_m) - pose.position_m) @ pose.rotation  # MuJoCo camera frame
        depth = -cam[:, 2]
        if (depth <= 0).all():
            return None
        if (depth <= 0).any():  # straddles the camera plane: no safe bound, read it all
            return 0, 0, width, height
        f = self.intrinsics(camera).f_px * ss
        u = width / 2 + f * cam[:, 0] / depth
        v = height / 2 - f * cam[:, 1] / depth
        if float(v.max() - v.min()) + SMALLEST_BOX_SLACK_SEG_PX < min_height_px * ss:
            return None
        x0, x1 = int(np.floor(u.min())) - 2, int(np.ceil(u.max())) + 2
        y0, y1 = int(np.floor(v.min())) - 2, int(np.ceil(v.max())) + 2
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
        return (x0, y0, x1, y1) if x0 < x1 and y0 < y1 else None

    def close(self) -> None:
        """Free the offscreen renderers and the cached frames; the rig renders nothing afterwards."""
        for renderer in (self._rgb, self._seg):
            if renderer is not None:
                renderer.close()
        self._rgb = self._seg = None
        self._last_rgb.clear()
