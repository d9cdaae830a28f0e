"""Detection loss: focal objectness, BCE classes, GIoU + L1 boxes.

Terms (all normalised so a batch with few signs still trains, and finite on a batch
with none):
  obj: sigmoid focal loss (Lin et al., ICCV 2017; alpha 0.25, gamma 2) over every cell,
       target 1 at positive cells, summed and divided by max(1, number of positives).
       Sign-free images add only negative terms, pushing objectness down.
  cls: binary cross-entropy of the class logits against one-hot targets, at positive
       cells, summed over classes, divided by max(1, number of positives).
  box: mean over positive cells of (1 - GIoU) plus the L1 distance between the raw
       (dx, dy, log_w, log_h) and their targets (`boxes.encode_boxes`); the log-size
       L1 term penalises the relative height error directly.
  total: weighted sum with `LossWeights`.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from avsim.perception.detector.assign import assign_targets
from avsim.perception.detector.boxes import decode_boxes, encode_boxes, flatten_outputs, generalized_iou
from avsim.perception.detector.model import STRIDES

FOCAL_ALPHA = 0.25
FOCAL_GAMMA = 2.0


@dataclass(frozen=True)
class LossWeights:
    """Weights of the loss terms in the total (module docstring): objectness, class and box."""

    obj: float = 1.0
    cls: float = 1.0
    box: float = 2.5


def sigmoid_focal_loss(logits: torch.Tensor, targets: torch.Tensor, alpha: float = FOCAL_ALPHA,
                       gamma: float = FOCAL_GAMMA) -> torch.Tensor:
    """Element-wise focal loss of logits against {0, 1} targets (same shape)."""
    p = torch.sigmoid(logits)
    ce = F.binary_cross_entropy_with_logits(logits, targets, reduction="none")
    p_t = p * targets + (1 - p) * (1 - targets)
    alpha_t = alpha * targets + (1 - alpha) * (1 - targets)
    return alpha_t * (1 - p_t) ** gamma * ce


def compute_loss(outputs: list[torch.Tensor], targets: list[dict[str, torch.Tensor]],
                 strides: tuple[int, ...] = STRIDES, weights: LossWeights = LossWeights()) -> dict[str, torch.Tensor]:
    """Loss terms {"obj", "cls", "box", "total"} (scalars) for a batch.

    outputs: the model's per-stride maps, each (B, 1 + C + 4, H_s, W_s).
    targets: per image {"boxes": (G, 4) xyxy [input px], "classes": (G,) int64 in [0, C)}.
    """
    preds, centres, cell_strides = flatten_outputs(outputs, strides)  # (B, N, K), (N, 2), (N,)
    num_classes = preds.shape[-1] - 5
    with torch.no_grad():
        assigned = assign_targets(targets, centres, cell_strides, strides)
    positive = assigned.positive
    num_pos = max(1.0, float(positive.sum()))

    obj = sigmoid_focal_loss(preds[..., 0], positive.to(preds.dtype)).sum() / num_pos

    pos_preds = preds[positive]  # (P, K)
    if pos_preds.shape[0] == 0:
        zero = preds.sum() * 0.0  # keeps the graph; an image set without signs trains objectness only
        cls, box = zero, zero
    else:
        cls_target = F.one_hot(assigned.classes[positive], num_classes).to(preds.dtype)
        cls = F.binary_cross_entropy_with_logits(pos_preds[:, 1:1 + num_classes], cls_target, reduction="sum") / num_pos
        pos_centres = centres.expand(positive.shape[0], -1, -1)[positive]
        pos_strides = cell_strides.expand(positive.shape[0], -1)[positive]
        raw_box = pos_preds[:, 1 + num_classes:]
        gt_box = assigned.boxes[positive]
        _, giou = generalized_iou(decode_boxes(raw_box, pos_centres, pos_strides), gt_box)
        l1 = (raw_box - encode_boxes(gt_box, pos_centres, pos_strides)).abs().sum(dim=1)
        box = (1.0 - giou).mean() + l1.mean()

    total = weights.obj * obj + weights.cls * cls + weights.box * box
    return {"obj": obj, "cls": cls, "box": box, "total": total}
