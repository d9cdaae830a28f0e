"""What a camera does between the light and the frame, beyond the pinhole: the photographic model.

A rasteriser samples each pixel at one point; a camera does not. In the order light meets them:

- **Lens** (`lens_mtf50_cyc_per_px`): a real lens does not focus a point to a point. Its blur is
  stated as a modulation transfer function (MTF); MTF50, the spatial frequency at which contrast
  falls to half, is the usual single figure (ISO 12233 slanted-edge measurement). A Gaussian
  point-spread function of standard deviation sigma [px] has MTF(f) = exp(-2 pi^2 sigma^2 f^2), so
  sigma = sqrt(ln 2 / 2) / (pi MTF50) = 0.1874 / MTF50. Applied at the sensor's resolution (blur and
  the pixel's box integration are both convolutions, so their order does not matter up to aliasing).
- **Photosite** (`supersample`): a pixel integrates the irradiance over its area (with microlenses,
  nearly all of it), which is a box filter before sampling: the frame is rendered at s times the
  resolution and area-averaged down (`cv2.INTER_AREA`, an exact box mean for an integer factor).
  This is anti-aliasing at the sensor. MuJoCo's own multisampling (`camera.offsamples`) is the
  renderer's approximation of the same, coverage-sampled at the edges only.
- **Sensor noise**: `avsim.sensors.noise`, output-referred (added in 8-bit levels); unchanged.
- **ISP encoding** (`jpeg_quality`): a camera that streams or stores compressed video encodes after
  the noise, so the JPEG round trip (OpenCV's libjpeg, 4:2:0 chroma) is applied last.

Every stage is off by default: the default frames are bit for bit those of the pinhole renderer.

Regions. A perception that reads part of a frame (`CameraRig.render_rgb(region_px=...)`) must get the
same pixels there as in a whole frame. A blurred pixel depends on its neighbours within the kernel's
radius, and a JPEG pixel on its 16x16 block (and, through chroma upsampling, one chroma sample
beyond): `PhotoModel.padded_region` widens the region by that much (aligned to the blocks), the
stages run on the padded part, and the caller keeps the region (a test checks equality).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from avsim.config import CameraConfig

# sigma [px] * MTF50 [cycles/px] of a Gaussian point-spread function: sqrt(ln 2 / 2) / pi.
GAUSSIAN_SIGMA_TIMES_MTF50 = math.sqrt(math.log(2) / 2) / math.pi
# The kernel reaches this many sigmas (0.3 % of a Gaussian's weight lies beyond 3 sigma).
KERNEL_SIGMAS = 3.0
# A JPEG's minimum coded unit with 4:2:0 chroma [px]: blocks are coded independently within it.
JPEG_BLOCK_PX = 16

Region = tuple[int, int, int, int]


@dataclass(frozen=True)
class PhotoModel:
    """The photographic stages of one camera config (see the module docstring).

    supersample: render scale factor (1: one sample per pixel). lens_sigma_px: Gaussian PSF standard
    deviation [px] (0: none). jpeg_quality: 1..100, or 0 for no encoding.
    """

    supersample: int = 1
    lens_sigma_px: float = 0.0
    jpeg_quality: int = 0

    @classmethod
    def from_config(cls, config: CameraConfig) -> "PhotoModel":
        """The stages a camera config asks for: its supersample, the lens sigma [px] from its MTF50
        [cycles/px] (0: no blur), its JPEG quality."""
        mtf50 = config.lens_mtf50_cyc_per_px
        return cls(config.supersample, GAUSSIAN_SIGMA_TIMES_MTF50 / mtf50 if mtf50 > 0 else 0.0, config.jpeg_quality)

    @property
    def lens_radius_px(self) -> int:
        """Half-width of the lens blur's kernel [px] (0 without blur)."""
        return math.ceil(KERNEL_SIGMAS * self.lens_sigma_px) if self.lens_sigma_px > 0 else 0

    def padded_region(self, region_px: Region | None, width_px: int, height_px: int) -> Region | None:
        """The part of a frame to render and process so that `region_px` comes out as in the whole
        frame: widened by the lens kernel's radius, then (with JPEG) by one block and out to block
        edges; clipped to the frame. None stays None (the whole frame)."""
        if region_px is None:
            return None
        x0, y0, x1, y1 = region_px
        pad = self.lens_radius_px
        x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
        if self.jpeg_quality:
            b = JPEG_BLOCK_PX
            x0, y0 = (x0 // b - 1) * b, (y0 // b - 1) * b
            x1, y1 = (-(-x1 // b) + 1) * b, (-(-y1 // b) + 1) * b
        return max(x0, 0), max(y0, 0), min(x1, width_px), min(y1, height_px)

    def integrate(self, rendered: np.ndarray) -> np.ndarray:
        """Photosite integration: (H s, W s, 3) uint8 rendered samples to (H, W, 3), a box mean per pixel."""
        s = self.supersample
        if s == 1:
            return rendered
        height, width = rendered.shape[0] // s, rendered.shape[1] // s
        return cv2.resize(rendered, (width, height), interpolation=cv2.INTER_AREA)

    def lens(self, frame: np.ndarray) -> np.ndarray:
        """The lens's Gaussian blur of an (H, W, 3) uint8 frame (the frame itself without blur)."""
        if self.lens_sigma_px == 0:
            return frame
        size = 2 * self.lens_radius_px + 1
        return cv2.GaussianBlur(frame, (size, size), self.lens_sigma_px, borderType=cv2.BORDER_REFLECT_101)

    def encode(self, frame: np.ndarray) -> np.ndarray:
        """The ISP's JPEG round trip of an (H, W, 3) uint8 RGB frame (the frame itself without it)."""
        if not self.jpeg_quality:
            return frame
        ok, buffer = cv2.imencode(".jpg", np.ascontiguousarray(frame[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise RuntimeError("OpenCV could not JPEG-encode a camera frame")
        return np.ascontiguousarray(cv2.imdecode(buffer, cv2.IMREAD_COLOR)[..., ::-1])
