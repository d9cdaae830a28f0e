"""What the attacks minimise: the detector's stop-sign evidence around the sign.

The detector (see `avsim.perception.detector.model`) scores each cell as
sigmoid(objectness) * sigmoid(stop-sign class logit). An attack wants every cell that
could report the sign to score low, so the objectives take the maximum over the cells
whose centres fall inside the sign's box, grown by a margin (a cell just outside the
box still predicts it). Cells elsewhere in the frame are not the attack's business.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.boxes import flatten_outputs

STOP_CLASS_INDEX = SIGN_CLASSES.index("stop_sign")


@dataclass(frozen=True)
class StopEvidence:
    """Per view (B,), the maximum over the sign's cells of each quantity, in [0, 1]."""

    score: torch.Tensor  # objectness x stop-sign class probability: what NMS thresholds
    objectness: torch.Tensor
    class_prob: torch.Tensor
    # The stop-sign class logit (unbounded): a clean sign saturates the sigmoid, whose
    # gradient then vanishes in float32, so a class-probability attack descends the logit.
    class_logit: torch.Tensor


def cells_near_boxes(centres_px: torch.Tensor, boxes_xyxy_px: torch.Tensor, margin_px: float) -> torch.Tensor:
    """(B, N) bool: cell centre (N, 2) [input px] inside box (B, 4) grown by `margin_px` on each side."""
    x, y = centres_px[None, :, 0], centres_px[None, :, 1]
    x0, y0, x1, y1 = (boxes_xyxy_px[:, i, None] for i in range(4))
    return (x >= x0 - margin_px) & (x <= x1 + margin_px) & (y >= y0 - margin_px) & (y <= y1 + margin_px)


def stop_evidence(outputs: list[torch.Tensor], strides: tuple[int, ...], sign_boxes_xyxy_px: torch.Tensor,
                  margin_px: float = 8.0) -> StopEvidence:
    """Stop-sign evidence near each view's sign.

    outputs: the detector's raw per-stride maps, each (B, 1 + C + 4, H_s, W_s);
    sign_boxes_xyxy_px: (B, 4) the sign's box in input pixels.
    A view with no cell near its box gets zeros (and no gradient).
    """
    preds, centres, _ = flatten_outputs(outputs, strides)  # (B, N, K)
    near = cells_near_boxes(centres, sign_boxes_xyxy_px.to(preds.dtype), margin_px)
    objectness = torch.sigmoid(preds[..., 0])
    class_prob = torch.sigmoid(preds[..., 1 + STOP_CLASS_INDEX])
    floor = torch.zeros((), dtype=preds.dtype)

    def masked_max(values: torch.Tensor, empty: torch.Tensor = floor) -> torch.Tensor:
        return torch.where(near, values, empty).amax(dim=1)

    logit_floor = torch.full((), -20.0, dtype=preds.dtype)
    return StopEvidence(masked_max(objectness * class_prob), masked_max(objectness), masked_max(class_prob),
                        masked_max(preds[..., 1 + STOP_CLASS_INDEX], logit_floor))
