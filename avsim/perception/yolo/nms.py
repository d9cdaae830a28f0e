"""Class-aware greedy non-maximum suppression in torch, without a loop over boxes.

Greedy NMS keeps a box when no *kept* box of its class with a higher score overlaps it with
IoU > threshold. That rule has exactly one solution, and it is reached by applying it to all
boxes at once, starting from "every box kept", until nothing changes: each pass settles at
least the next box of every suppression chain, so the passes are as many as the longest
chain (one to three on camera frames), each a few (N, N) tensor operations.
"""

from __future__ import annotations

import torch


def pairwise_iou(boxes_xyxy: torch.Tensor) -> torch.Tensor:
    """(N, 4) x1, y1, x2, y2 -> (N, N) intersection over union."""
    area = (boxes_xyxy[:, 2] - boxes_xyxy[:, 0]).clamp(min=0) * (boxes_xyxy[:, 3] - boxes_xyxy[:, 1]).clamp(min=0)
    top_left = torch.maximum(boxes_xyxy[:, None, :2], boxes_xyxy[None, :, :2])
    bottom_right = torch.minimum(boxes_xyxy[:, None, 2:], boxes_xyxy[None, :, 2:])
    inter = (bottom_right - top_left).clamp(min=0).prod(dim=-1)
    union = area[:, None] + area[None, :] - inter
    return torch.where(union > 0, inter / union, torch.zeros_like(inter))


def batched_nms(boxes_xyxy: torch.Tensor, scores: torch.Tensor, classes: torch.Tensor,
                iou_threshold: float) -> torch.Tensor:
    """Kept indices (K,) int64, highest score first (ties: lower index first).

    boxes_xyxy: (N, 4) [px]; scores: (N,); classes: (N,) ints. Boxes of different classes never
    suppress each other.
    """
    if boxes_xyxy.shape[0] == 0:
        return torch.zeros(0, dtype=torch.int64)
    order = torch.argsort(scores, descending=True, stable=True)
    boxes, labels = boxes_xyxy[order].double(), classes[order]
    count = order.shape[0]
    higher = torch.ones(count, count, dtype=torch.bool).triu(diagonal=1).T  # [i, j]: j ranks above i
    suppressor = higher & (labels[:, None] == labels[None, :]) & (pairwise_iou(boxes) > iou_threshold)
    keep = torch.ones(count, dtype=torch.bool)
    for _ in range(count):
        updated = ~(suppressor & keep[None, :]).any(dim=1)
        if torch.equal(updated, keep):
            break
        keep = updated
    return order[keep]
