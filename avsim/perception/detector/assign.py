"""Target assignment by centre sampling (FCOS-style, simplified).

A ground-truth box is a candidate at a cell when
  1. its size max(w, h) lies in the cell's scale range (`SCALE_RANGES_PX`, overlapping so
     boxes near the boundary train both scales; NMS removes the duplicate), and
  2. the cell centre lies within r_x, r_y of the box centre, per axis, with
     r_x = max(min(radius * s, w / 2), s / 2) (likewise r_y): a few cells near the centre
     of a large box; for a tiny box at least the cell holding its centre.
A cell that is a candidate for several boxes takes the smallest one (by area).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from avsim.perception.detector.model import STRIDES

SCALE_RANGES_PX = ((0.0, 64.0), (32.0, math.inf))  # per stride in STRIDES: box max(w, h) [input px]
CENTRE_RADIUS = 1.0  # [strides]


@dataclass(frozen=True)
class Assignment:
    """Per-cell targets for a batch of B images over N cells (all scales, `boxes.flatten_outputs` order).

    positive: (B, N) bool.
    boxes: (B, N, 4) xyxy [input px] of the assigned ground truth (zeros where not positive).
    classes: (B, N) int64 class index (-1 where not positive).
    """

    positive: torch.Tensor
    boxes: torch.Tensor
    classes: torch.Tensor


def _cell_ranges(cell_strides: torch.Tensor, strides: tuple[int, ...],
                 scale_ranges: tuple[tuple[float, float], ...]) -> tuple[torch.Tensor, torch.Tensor]:
    low = torch.full_like(cell_strides, math.inf)
    high = torch.full_like(cell_strides, -math.inf)
    for stride, (lo, hi) in zip(strides, scale_ranges):
        at_stride = cell_strides == float(stride)
        low[at_stride] = lo
        high[at_stride] = hi
    return low, high


def assign_targets(targets: list[dict[str, torch.Tensor]], centres: torch.Tensor, cell_strides: torch.Tensor,
                   strides: tuple[int, ...] = STRIDES,
                   scale_ranges: tuple[tuple[float, float], ...] = SCALE_RANGES_PX,
                   radius: float = CENTRE_RADIUS) -> Assignment:
    """Assign ground truth to cells.

    targets: per image {"boxes": (G, 4) xyxy [input px], "classes": (G,) int64}.
    centres: (N, 2) cell centres [input px]; cell_strides: (N,) [px].
    """
    if len(strides) != len(scale_ranges):
        raise ValueError(f"{len(strides)} strides but {len(scale_ranges)} scale ranges")
    n_cells = centres.shape[0]
    low, high = _cell_ranges(cell_strides, strides, scale_ranges)
    positive = torch.zeros(len(targets), n_cells, dtype=torch.bool, device=centres.device)
    boxes = torch.zeros(len(targets), n_cells, 4, device=centres.device)
    classes = torch.full((len(targets), n_cells), -1, dtype=torch.long, device=centres.device)
    for i, target in enumerate(targets):
        gt = target["boxes"].to(centres.device, torch.float32).reshape(-1, 4)
        if gt.shape[0] == 0:
            continue
        wh = (gt[:, 2:] - gt[:, :2]).clamp(min=0)  # (G, 2)
        size = wh.max(dim=1).values  # (G,)
        in_range = (size[None, :] >= low[:, None]) & (size[None, :] <= high[:, None])  # (N, G)
        s = cell_strides[:, None, None]  # (N, 1, 1)
        reach = torch.maximum(torch.minimum(radius * s, 0.5 * wh[None]), 0.5 * s)  # (N, G, 2)
        offset = (centres[:, None, :] - 0.5 * (gt[None, :, :2] + gt[None, :, 2:])).abs()  # (N, G, 2)
        candidate = in_range & (offset <= reach).all(dim=2)
        area = wh[:, 0] * wh[:, 1]
        cost = torch.where(candidate, area[None, :].expand_as(candidate), torch.full_like(candidate, math.inf, dtype=torch.float32))
        best = cost.argmin(dim=1)  # (N,)
        positive[i] = candidate.any(dim=1)
        boxes[i] = torch.where(positive[i, :, None], gt[best], torch.zeros_like(gt[best]))
        classes[i] = torch.where(positive[i], target["classes"].to(centres.device)[best], torch.full_like(best, -1))
    return Assignment(positive, boxes, classes)
