"""Camera frame -> YOLO input, by `perception.yolo_input`, reusing the COCO path's windows.

- `resize`: the whole image resized to the cfg's [net] width x height (416 x 416 for
  YOLOv3-tiny), without keeping the aspect ratio, as OpenCV's `blobFromImage` feeds
  Darknet models: bilinear with half-pixel centres (`cv2.resize`'s INTER_LINEAR), no
  antialiasing.
- `crop`: the region of interest at the camera's own resolution.
- `upscale`: the region of interest enlarged by `perception.yolo_upscale` (same bilinear).
Crop and upscale inputs are padded with black on the right and bottom to a multiple of the
network's downsampling (32); boxes map back through `coco.preprocess.InputWindow`.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from avsim.config import COCO_INPUTS
from avsim.perception.coco.preprocess import InputWindow, Region, clip_region


def resize_bilinear(x: torch.Tensor, size_hw: tuple[int, int]) -> torch.Tensor:
    """(B, C, H, W) -> (B, C, *size_hw): bilinear, half-pixel centres, no antialiasing (cv2 INTER_LINEAR)."""
    if tuple(x.shape[-2:]) == tuple(size_hw):
        return x
    return F.interpolate(x, size=size_hw, mode="bilinear", align_corners=False, antialias=False)


def network_input(image: torch.Tensor, mode: str, net_size_px: tuple[int, int], size_multiple_px: int,
                  region_px: Region | None = None, upscale: float = 2.0) -> tuple[torch.Tensor, InputWindow]:
    """(1, 3, H, W) float RGB 0-255 -> ((1, 3, H_in, W_in) network input, its InputWindow).

    The input comes in channels-last memory, which oneDNN's convolutions run fastest on (about
    1.4x in float32 and 2x in bfloat16 at 704 x 512 here).
    net_size_px: the cfg's (width, height), used by `resize`; size_multiple_px: what crop and
    upscale inputs are padded to. Differentiable in `image`.
    """
    height, width = image.shape[-2:]
    if mode == "resize":
        net_w, net_h = net_size_px
        x, window = resize_bilinear(image, (net_h, net_w)), InputWindow(0, 0, net_w / width, net_h / height, net_w, net_h)
        return x.contiguous(memory_format=torch.channels_last), window
    if mode not in COCO_INPUTS:
        raise ValueError(f"unknown YOLO input mode {mode!r}; choose one of: {', '.join(COCO_INPUTS)}")
    x0, y0, x1, y1 = clip_region(region_px, width, height)
    scale = upscale if mode == "upscale" else 1.0
    out_w, out_h = round((x1 - x0) * scale), round((y1 - y0) * scale)
    x = resize_bilinear(image[..., y0:y1, x0:x1], (out_h, out_w))
    x = F.pad(x, (0, -out_w % size_multiple_px, 0, -out_h % size_multiple_px))
    return x.contiguous(memory_format=torch.channels_last), InputWindow(x0, y0, out_w / (x1 - x0), out_h / (y1 - y0), out_w, out_h)
