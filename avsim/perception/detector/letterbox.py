"""Letterbox: fit an image into the network input, keeping its aspect ratio, and map boxes.

Coordinates are continuous pixels (pixel i covers [i, i+1)). The map is
    x_in = scale * x_img + pad_x,   y_in = scale * y_img + pad_y
with scale = min(W_in / W, H_in / H) and the image centred (integer pads); the rest of
the input is grey 114/255. The image is resampled with exactly this map
(`cv2.warpAffine`, bilinear), so box coordinates transform exactly. A 640x480 camera
frame at the deployed 640x480 input is the identity (scale 1, no pads, no resampling).
Bilinear downscaling aliases below scale 0.5; camera frames never need that.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch

from avsim.perception.detector.model import DEPLOY_INPUT_SIZE

PAD_VALUE = 114  # grey, of 255


@dataclass(frozen=True)
class Letterbox:
    """The map from image pixels to input pixels: x_in = scale * x_img + pad_x (same for y).

    in_w, in_h: the network input size [px].
    """

    scale: float
    pad_x: float
    pad_y: float
    in_w: int
    in_h: int

    def to_input(self, boxes: np.ndarray) -> np.ndarray:
        """(N, 4) xyxy in image pixels -> (N, 4) float64 xyxy in input pixels."""
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        return boxes * self.scale + np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y])

    def to_image(self, boxes: np.ndarray) -> np.ndarray:
        """(N, 4) xyxy in input pixels -> (N, 4) float64 xyxy in image pixels."""
        boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        return (boxes - np.array([self.pad_x, self.pad_y, self.pad_x, self.pad_y])) / self.scale

    def is_identity(self, image_w: int, image_h: int) -> bool:
        """True when an image_w x image_h image is the network input as it is (no scaling, no padding)."""
        return self.scale == 1.0 and self.pad_x == 0 and self.pad_y == 0 and (self.in_w, self.in_h) == (image_w, image_h)


def fit(image_w: int, image_h: int, input_size: tuple[int, int]) -> Letterbox:
    """The centred, aspect-preserving letterbox of a W x H image into input_size = (W_in, H_in)."""
    in_w, in_h = input_size
    if image_w <= 0 or image_h <= 0 or in_w <= 0 or in_h <= 0:
        raise ValueError(f"image {image_w}x{image_h} and input {in_w}x{in_h} must be non-empty")
    scale = min(in_w / image_w, in_h / image_h)
    pad_x = (in_w - round(image_w * scale)) // 2
    pad_y = (in_h - round(image_h * scale)) // 2
    return Letterbox(float(scale), float(pad_x), float(pad_y), int(in_w), int(in_h))


def warp(image: np.ndarray, box: Letterbox) -> np.ndarray:
    """Resample an (H, W, 3) uint8 image into the (in_h, in_w, 3) input through `box` (grey outside)."""
    h, w = image.shape[:2]
    if box.is_identity(w, h):
        return image
    s = box.scale
    # warpAffine maps pixel *indices* (centres at i + 0.5 in continuous coordinates):
    # (x_in + 0.5) = s * (x_img + 0.5) + pad  <=>  x_in = s * x_img + (pad + 0.5 * s - 0.5)
    matrix = np.array([[s, 0.0, box.pad_x + 0.5 * s - 0.5], [0.0, s, box.pad_y + 0.5 * s - 0.5]])
    return cv2.warpAffine(image, matrix, (box.in_w, box.in_h), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(PAD_VALUE, PAD_VALUE, PAD_VALUE))


def to_tensor(image: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 -> (3, H, W) float32 in [0, 1]; a permuted view, i.e. channels-last memory."""
    return torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1).float().mul_(1.0 / 255.0)


def check_image(image_rgb: np.ndarray) -> None:
    """ValueError unless `image_rgb` is an (H, W, 3) uint8 array."""
    if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got shape {image_rgb.shape} dtype {image_rgb.dtype}")


def letterbox(image_rgb: np.ndarray, input_size: tuple[int, int] = DEPLOY_INPUT_SIZE) -> tuple[torch.Tensor, Letterbox]:
    """(H, W, 3) uint8 RGB image -> ((3, H_in, W_in) float32 in [0, 1], its Letterbox); input_size is (W_in, H_in)."""
    check_image(image_rgb)
    box = fit(image_rgb.shape[1], image_rgb.shape[0], input_size)
    return to_tensor(warp(image_rgb, box)), box
