"""Train-time augmentation that keeps boxes exact.

Geometry: with probability `scale_prob` the letterbox scale is multiplied by a factor in
`scale_range` and the image is placed at a random offset (a random crop when it grows,
random padding when it shrinks); this is still a letterbox map x_in = scale * x + pad,
so boxes go through `Letterbox.to_input` exactly and are then clipped to the input. A
box keeps its label only if at least `min_visible` of its area stays inside. The other
samples keep the plain letterbox, i.e. the unresampled camera pixels seen at deployment.
No flips: a mirrored sign would have mirrored text.
Photometric (boxes unchanged): HSV gain/shift, contrast/brightness, Gaussian blur,
Gaussian pixel noise. All randomness comes from the `numpy.random.Generator` passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from avsim.perception.detector.letterbox import Letterbox


@dataclass(frozen=True)
class AugmentConfig:
    """Training-time augmentation of the detector (module docstring): the probability and range
    of a rescale (a factor of the letterbox scale), HSV and contrast jitter (hue in OpenCV units,
    180 per turn; brightness in grey levels), Gaussian blur [px] and noise [grey levels], and which
    boxes survive a crop (at least `min_visible` of their area, at least `min_box_px` [px] a side)."""

    scale_prob: float = 0.5
    scale_range: tuple[float, float] = (0.8, 1.2)
    hue_shift: float = 4.0  # [OpenCV hue units, 180 per turn]: +-8 deg keeps red signs red
    saturation_gain: tuple[float, float] = (0.7, 1.3)
    value_gain: tuple[float, float] = (0.7, 1.3)
    contrast: tuple[float, float] = (0.8, 1.2)
    brightness: tuple[float, float] = (-20.0, 20.0)  # [grey levels]
    blur_prob: float = 0.15
    blur_sigma_px: tuple[float, float] = (0.3, 1.0)
    noise_prob: float = 0.5
    noise_sigma: tuple[float, float] = (1.0, 6.0)  # [grey levels]
    min_visible: float = 0.4
    min_box_px: float = 2.0


def jitter_letterbox(base: Letterbox, image_w: int, image_h: int, config: AugmentConfig,
                     rng: np.random.Generator) -> Letterbox:
    """A randomly rescaled and shifted version of `base` (or `base` itself, with probability 1 - scale_prob)."""
    if rng.random() >= config.scale_prob:
        return base
    scale = base.scale * float(rng.uniform(*config.scale_range))
    free_x = base.in_w - image_w * scale  # < 0: the image overflows and is cropped
    free_y = base.in_h - image_h * scale
    pad_x = float(rng.uniform(min(0.0, free_x), max(0.0, free_x)))
    pad_y = float(rng.uniform(min(0.0, free_y), max(0.0, free_y)))
    return Letterbox(scale, pad_x, pad_y, base.in_w, base.in_h)


def clip_boxes(boxes: np.ndarray, classes: np.ndarray, in_w: int, in_h: int, min_visible: float,
               min_box_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip (N, 4) input-pixel boxes to the input; drop those less than `min_visible` inside or thinner than `min_box_px`."""
    if len(boxes) == 0:
        return boxes.reshape(0, 4), classes.reshape(0)
    clipped = np.clip(boxes, 0.0, [in_w, in_h, in_w, in_h])
    area = np.prod(np.clip(boxes[:, 2:] - boxes[:, :2], 0.0, None), axis=1)
    wh = np.clip(clipped[:, 2:] - clipped[:, :2], 0.0, None)
    keep = (wh.min(axis=1) >= min_box_px) & (np.prod(wh, axis=1) >= min_visible * area)
    return clipped[keep], classes[keep]


def photometric(image: np.ndarray, config: AugmentConfig, rng: np.random.Generator) -> np.ndarray:
    """Colour, contrast, blur and noise jitter of an (H, W, 3) uint8 RGB image; returns a new image."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    levels = np.arange(256, dtype=np.float32)
    hue_lut = np.mod(levels + rng.uniform(-config.hue_shift, config.hue_shift), 180.0)
    sat_lut = np.clip(levels * rng.uniform(*config.saturation_gain), 0, 255)
    val_lut = np.clip(levels * rng.uniform(*config.value_gain), 0, 255)
    luts = [lut.astype(np.uint8) for lut in (hue_lut, sat_lut, val_lut)]
    hsv = cv2.merge([cv2.LUT(channel, lut) for channel, lut in zip(cv2.split(hsv), luts)])
    out = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    contrast_lut = np.clip((levels - 128.0) * rng.uniform(*config.contrast) + 128.0 + rng.uniform(*config.brightness), 0, 255)
    out = cv2.LUT(out, contrast_lut.astype(np.uint8))
    if rng.random() < config.blur_prob:
        out = cv2.GaussianBlur(out, (0, 0), float(rng.uniform(*config.blur_sigma_px)))
    if rng.random() < config.noise_prob:
        noise = rng.standard_normal(out.shape, dtype=np.float32) * np.float32(rng.uniform(*config.noise_sigma))
        out = np.clip(out.astype(np.float32) + noise, 0, 255).astype(np.uint8)
    return out
