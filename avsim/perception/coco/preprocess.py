"""Camera frame -> CenterNet input, and the network's boxes back to image pixels.

`perception.coco_input` chooses how a frame (or a region of it) becomes the network input:
- `resize`: the whole image resized to 512 x 512, as @vladmandic/human feeds the graph
  (`src/object/centernet.ts`: `tf.image.resizeBilinear(input, [512, 512])`, no corner
  alignment, no half-pixel centres, no aspect preservation) and its boxes scaled back by
  W/512 and H/512, as that library does. A 640x480 frame is squeezed to 0.8 of its width.
- `crop`: the region of interest at the camera's own resolution (scale 1).
- `upscale`: the region of interest resized by `coco_upscale` (TF's legacy bilinear resize).
Crop and upscale inputs are padded with black on the right and bottom to a multiple of 32,
which the network needs; the padding is outside the region and reports nothing.

Coordinates are continuous pixels. The map is x_in = (x_img - origin_x) * scale_x (same
for y), and a box maps back with its inverse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from avsim.config import COCO_INPUTS
from avsim.perception.coco.model import GRAPH_INPUT_SIZE_PX
from avsim.perception.coco.network import SIZE_MULTIPLE_PX
from avsim.perception.coco.ops import resize_bilinear_tf, upsample_bilinear_tf, upscale_bilinear_tf
from avsim.perception.detector import roi

Region = tuple[int, int, int, int]


@dataclass(frozen=True)
class InputWindow:
    """Where the network input comes from: x_in = (x_img - origin_x) * scale_x, likewise y.

    content_w, content_h: the input pixels that hold image content [px]; the input itself
    is padded up to a multiple of 32.
    """

    origin_x: int
    origin_y: int
    scale_x: float
    scale_y: float
    content_w: int
    content_h: int

    def to_image(self, boxes_xyxy: np.ndarray) -> np.ndarray:
        """(N, 4) boxes in input pixels -> (N, 4) float64 boxes in image pixels."""
        boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
        scale = np.array([self.scale_x, self.scale_y, self.scale_x, self.scale_y])
        return boxes / scale + np.array([self.origin_x, self.origin_y, self.origin_x, self.origin_y])


def clip_region(region_px: Region | None, width_px: int, height_px: int) -> Region:
    """The region clipped to a W x H image (None: the whole image); ValueError if nothing is left."""
    if region_px is None:
        return 0, 0, width_px, height_px
    return roi.clip_region(region_px, width_px, height_px)


def _pad_to_multiple(x: torch.Tensor) -> torch.Tensor:
    height, width = x.shape[-2:]
    pad_h = -height % SIZE_MULTIPLE_PX
    pad_w = -width % SIZE_MULTIPLE_PX
    return F.pad(x, (0, pad_w, 0, pad_h)) if pad_h or pad_w else x


def image_tensor(image_rgb: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 RGB -> (1, 3, H, W) float32 0-255, channels-last memory (a permuted view)."""
    return torch.from_numpy(np.ascontiguousarray(image_rgb)).permute(2, 0, 1).unsqueeze(0).float()


def network_input(image: torch.Tensor, mode: str, region_px: Region | None = None,
                  upscale: float = 2.0) -> tuple[torch.Tensor, InputWindow]:
    """(1, 3, H, W) float RGB 0-255 -> ((1, 3, H_in, W_in) network input, its InputWindow).

    Differentiable in `image`. region_px: (x0, y0, x1, y1) [px] for `crop` and `upscale`
    (None: the whole image); `resize` always takes the whole image.
    """
    height, width = image.shape[-2:]
    if mode == "resize":
        size = GRAPH_INPUT_SIZE_PX
        window = InputWindow(0, 0, size / width, size / height, size, size)
        x = resize_bilinear_tf(image, (size, size))
    elif mode in ("crop", "upscale"):
        x0, y0, x1, y1 = clip_region(region_px, width, height)
        x = image[..., y0:y1, x0:x1]
        scale = upscale if mode == "upscale" else 1.0
        out_w, out_h = round((x1 - x0) * scale), round((y1 - y0) * scale)
        if scale in (2, 4):  # TF's samples, bit for bit, in a few strided passes
            x = upscale_bilinear_tf(x, int(scale))
        elif scale == int(scale) and scale > 1:  # the same samples, in one native kernel
            x = upsample_bilinear_tf(x, (int(scale), int(scale)))
        elif (out_w, out_h) != (x1 - x0, y1 - y0):
            x = resize_bilinear_tf(x, (out_h, out_w))
        window = InputWindow(x0, y0, out_w / (x1 - x0), out_h / (y1 - y0), out_w, out_h)
        x = _pad_to_multiple(x)
    else:
        raise ValueError(f"unknown COCO input mode {mode!r}; choose one of: {', '.join(COCO_INPUTS)}")
    return x.contiguous(memory_format=torch.channels_last), window
