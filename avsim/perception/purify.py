"""Input purification: the frame is cleaned before the network sees it (`perception.purify`).

The classic cheap defence against adversarial pixels: transform the input so that a finely
tuned perturbation no longer survives, while the scene's content does.

- `jpeg`: re-compress the frame as JPEG at `perception.purify_jpeg_quality` and decode it
  (Dziugaite et al. 2016, "A study of the effect of JPG compression on adversarial images";
  Das et al. 2017; Armory's JPEG defence measured attacked mAP 0.66 defended against 0.68
  undefended, clean 0.76 -> 0.72). Assumes the perturbation lives in high spatial frequencies
  that JPEG's quantisation removes.
- `median`: a `perception.purify_median_kernel_px` square median filter (Xu et al. 2018,
  "Feature squeezing", its local smoothing squeezer). Assumes the perturbation is sparse or
  high-frequency noise that a median replaces by its neighbours.

Both are known to fall to an adaptive attacker who differentiates through them with BPDA
(Athalye, Carlini and Wagner 2018): `avsim.attacks.bpda` wraps `purify_tensor` for that.

A purifier maps an (H, W, 3) uint8 RGB frame to one of the same shape; it is deterministic
(OpenCV's codec and filter), so a purified run is as reproducible as any other.
`PurifiedDetector` puts one in front of any frame detector (`perception.frame.FrameDetector`).
The whole frame is purified, as a camera's codec would compress it, before the detector
crops its region of interest.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import torch

from avsim.config import PerceptionConfig
from avsim.perception.base import Detection
from avsim.perception.frame import FrameDetector, Region

Purifier = Callable[[np.ndarray], np.ndarray]


def jpeg_recompress(image_rgb: np.ndarray, quality: int) -> np.ndarray:
    """The frame encoded as JPEG at `quality` (1-100, OpenCV's libjpeg, 4:2:0) and decoded again."""
    ok, encoded = cv2.imencode(".jpg", np.ascontiguousarray(image_rgb[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV could not encode a frame as JPEG")
    return np.ascontiguousarray(cv2.imdecode(encoded, cv2.IMREAD_COLOR)[..., ::-1])


def median_blur(image_rgb: np.ndarray, kernel_px: int) -> np.ndarray:
    """Each channel's median over a `kernel_px` square (odd) around every pixel (borders replicated)."""
    return cv2.medianBlur(np.ascontiguousarray(image_rgb), int(kernel_px))


def build_purifier(config: PerceptionConfig) -> Purifier | None:
    """The configured purifier; None for `purify = "none"`."""
    if config.purify == "jpeg":
        return lambda image: jpeg_recompress(image, config.purify_jpeg_quality)
    if config.purify == "median":
        return lambda image: median_blur(image, config.purify_median_kernel_px)
    return None


def purify_tensor(images: torch.Tensor, purifier: Purifier) -> torch.Tensor:
    """`purifier` applied to a batch of images as the deployed perception applies it.

    images: [B, 3, H, W] float in [0, 1]. Each image is quantised to 8 bits, as a rendered
    frame is, purified, and returned as float in [0, 1], same shape, device and dtype. Not
    differentiable: wrap it with `avsim.attacks.bpda.bpda` to pass gradients through.
    """
    frames = (images.detach().clamp(0, 1) * 255).round().to(torch.uint8).permute(0, 2, 3, 1).cpu().numpy()
    purified = np.stack([purifier(np.ascontiguousarray(frame)) for frame in frames])
    return torch.from_numpy(purified).permute(0, 3, 1, 2).to(device=images.device, dtype=images.dtype) / 255


class PurifiedDetector:
    """A frame detector that purifies each frame before `inner` sees it (a `FrameDetector`)."""

    def __init__(self, inner: FrameDetector, purifier: Purifier) -> None:
        self.inner = inner
        self.purifier = purifier

    def detect(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None) -> list[Detection]:
        """The inner detector's detections on the purified image (same size, so boxes need no mapping)."""
        return self.inner.detect(self.purifier(image_rgb), camera, region_px=region_px)
