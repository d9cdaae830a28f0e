"""Cell grids and the box parametrisation, shared by the loss and the postprocess.

A cell (row i, column j) of a stride-s map covers input pixels [j*s, (j+1)*s) x
[i*s, (i+1)*s); its centre is ((j + 0.5) s, (i + 0.5) s). A box is predicted as
(dx, dy, log_w, log_h) [strides, strides, log(strides), log(strides)]:
  centre = cell centre + (dx, dy) * s,  (w, h) = exp(log_w, log_h) * s   [input pixels]
Regressing log(h / s) makes the height error relative, which is what a range estimate
from the box height needs.
"""

from __future__ import annotations

import functools
import math

import torch

MAX_LOG_SIZE = math.log(4096.0 / 8.0)  # clamp before exp: no box larger than 4096 px at stride 8


def cell_centres(height: int, width: int, stride: int, device: torch.device | str = "cpu") -> torch.Tensor:
    """(height * width, 2) cell centres (x, y) [input pixels], row-major like `Tensor.flatten(2)`."""
    ys = (torch.arange(height, device=device, dtype=torch.float32) + 0.5) * stride
    xs = (torch.arange(width, device=device, dtype=torch.float32) + 0.5) * stride
    grid_y, grid_x = torch.meshgrid(ys, xs, indexing="ij")
    return torch.stack([grid_x.reshape(-1), grid_y.reshape(-1)], dim=1)


def flatten_outputs(outputs: list[torch.Tensor], strides: tuple[int, ...]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Concatenate per-scale maps into one cell list.

    outputs: per stride, (B, K, H_s, W_s).
    Returns preds (B, N, K), centres (N, 2) [input px] and cell strides (N,) [px],
    N = sum over scales of H_s * W_s. The centres and strides are shared between calls with the
    same map sizes (`_cell_grid`): read them, never write into them.
    """
    if len(outputs) != len(strides):
        raise ValueError(f"got {len(outputs)} output maps for {len(strides)} strides")
    preds = [out.reshape(out.shape[0], out.shape[1], out.shape[2] * out.shape[3]).transpose(1, 2) for out in outputs]
    shapes = tuple((out.shape[2], out.shape[3], stride) for out, stride in zip(outputs, strides))
    centres, cell_strides = _cell_grid(shapes, str(outputs[0].device))
    return torch.cat(preds, dim=1), centres, cell_strides


@functools.lru_cache(maxsize=64)
def _cell_grid(shapes: tuple[tuple[int, int, int], ...], device: str) -> tuple[torch.Tensor, torch.Tensor]:
    """Cell centres (N, 2) [input px] and strides (N,) [px] of maps of these (H_s, W_s, stride) on `device`.

    Cached because building the grid was about a quarter of decoding a frame's detections, at every
    control step, for maps whose sizes never change within a run. Built outside inference mode, so
    that a grid first made while detecting can later enter a loss or an attack's objective, where
    autograd saves it.
    """
    with torch.inference_mode(False):
        centres = torch.cat([cell_centres(h, w, stride, device) for h, w, stride in shapes], dim=0)
        cell_strides = torch.cat([torch.full((h * w,), float(stride), device=device) for h, w, stride in shapes], dim=0)
    return centres, cell_strides


def decode_boxes(raw: torch.Tensor, centres: torch.Tensor, strides: torch.Tensor) -> torch.Tensor:
    """(..., 4) raw (dx, dy, log_w, log_h) at cells with centres (..., 2) and strides (...,) -> (..., 4) xyxy [input px]."""
    s = strides.unsqueeze(-1)
    centre = centres + raw[..., :2] * s
    half = 0.5 * torch.exp(raw[..., 2:].clamp(max=MAX_LOG_SIZE)) * s
    return torch.cat([centre - half, centre + half], dim=-1)


def encode_boxes(xyxy: torch.Tensor, centres: torch.Tensor, strides: torch.Tensor) -> torch.Tensor:
    """Inverse of `decode_boxes`: (..., 4) xyxy [input px] -> (..., 4) (dx, dy, log_w, log_h); boxes need w, h > 0."""
    s = strides.unsqueeze(-1)
    centre = 0.5 * (xyxy[..., :2] + xyxy[..., 2:])
    size = (xyxy[..., 2:] - xyxy[..., :2]).clamp(min=1e-3)
    return torch.cat([(centre - centres) / s, torch.log(size / s)], dim=-1)


def generalized_iou(a: torch.Tensor, b: torch.Tensor, eps: float = 1e-7) -> tuple[torch.Tensor, torch.Tensor]:
    """Element-wise IoU and GIoU (Rezatofighi et al., CVPR 2019) of (..., 4) xyxy boxes -> two (...,) tensors.

    GIoU = IoU - |C \\ (A u B)| / |C|, C the smallest box enclosing A and B; in [-1, 1].
    """
    area_a = (a[..., 2] - a[..., 0]).clamp(min=0) * (a[..., 3] - a[..., 1]).clamp(min=0)
    area_b = (b[..., 2] - b[..., 0]).clamp(min=0) * (b[..., 3] - b[..., 1]).clamp(min=0)
    inter_wh = (torch.minimum(a[..., 2:], b[..., 2:]) - torch.maximum(a[..., :2], b[..., :2])).clamp(min=0)
    inter = inter_wh[..., 0] * inter_wh[..., 1]
    union = area_a + area_b - inter
    iou = inter / (union + eps)
    hull_wh = (torch.maximum(a[..., 2:], b[..., 2:]) - torch.minimum(a[..., :2], b[..., :2])).clamp(min=0)
    hull = hull_wh[..., 0] * hull_wh[..., 1]
    return iou, iou - (hull - union) / (hull + eps)
