"""What the attacks minimise: a detector's stop-sign evidence around the sign, and how the car
turns that evidence into a decision.

Per view (`StopEvidence`), from the detector's dense maps before non-maximum suppression:
- the stop-sign score of the cells that could report the sign: the maximum over the cells
  whose centres fall inside the sign's box, grown by a margin (a cell just outside the box
  still predicts it); cells elsewhere in the frame are not the attack's business;
- the height of the box those cells would report: their predicted heights weighted by a
  softmax of their scores, since NMS keeps the best-scored one.

Over a drive-by (`driveby_objective`), the quantity that decides `baseline` is the *first*
confident frame inside the braking gate, so the objective is a soft maximum over a whole
approach sequence, not a mean. `gate_weight` is the braking gate itself, made smooth: a frame
counts only once the policy's pinhole estimate, computed from the *predicted* box height, is
inside the trigger distance, so a box read short (range inflation) keeps a frame out of it.
Against a k-of-n temporal vote the decision is a window's k-th best frame
(`kth_largest_in_windows`), and the soft maximum runs over windows instead of frames.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import torch

from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.boxes import MAX_LOG_SIZE, flatten_outputs

STOP_CLASS_INDEX = SIGN_CLASSES.index("stop_sign")
# Softmax temperature over cell scores for the reported box's height: 0.05 puts nearly all the
# weight on the best cells, as NMS does, and still passes gradient to their neighbours.
BOX_SCORE_TEMPERATURE = 0.05


@dataclass(frozen=True)
class StopEvidence:
    """Per view (B,), the maximum over the sign's cells of each quantity; scores in [0, 1].

    box_height_px: height [camera image px] of the box the sign's cells would report.
    """

    score: torch.Tensor  # objectness x stop-sign class probability: what NMS thresholds
    objectness: torch.Tensor
    class_prob: torch.Tensor
    # The stop-sign class logit (unbounded): a clean sign saturates the sigmoid, whose
    # gradient then vanishes in float32, so a class-probability attack descends the logit.
    class_logit: torch.Tensor
    box_height_px: torch.Tensor


def cells_near_boxes(centres_px: torch.Tensor, boxes_xyxy_px: torch.Tensor, margin_px: float) -> torch.Tensor:
    """(B, N) bool: cell centre (N, 2) [input px] inside box (B, 4) grown by `margin_px` on each side."""
    x, y = centres_px[None, :, 0], centres_px[None, :, 1]
    x0, y0, x1, y1 = (boxes_xyxy_px[:, i, None] for i in range(4))
    return (x >= x0 - margin_px) & (x <= x1 + margin_px) & (y >= y0 - margin_px) & (y <= y1 + margin_px)


def masked_max(values: torch.Tensor, near: torch.Tensor, empty: float) -> torch.Tensor:
    """(B, N) values, (B, N) mask -> (B,) the maximum over the masked cells (`empty` if none)."""
    return torch.where(near, values, torch.full((), empty, dtype=values.dtype)).amax(dim=1)


def reported_height_px(heights_px: torch.Tensor, scores: torch.Tensor, near: torch.Tensor) -> torch.Tensor:
    """(B,) the near cells' box heights (B, N) weighted by softmax(score / BOX_SCORE_TEMPERATURE)."""
    logits = torch.where(near, scores / BOX_SCORE_TEMPERATURE, torch.full((), -1e4, dtype=scores.dtype))
    weights = torch.softmax(logits, dim=1) * near.any(dim=1, keepdim=True)
    return (weights * heights_px).sum(dim=1)


def stop_evidence(outputs: list[torch.Tensor], strides: tuple[int, ...], sign_boxes_xyxy_px: torch.Tensor,
                  margin_px: float = 8.0) -> StopEvidence:
    """Stop-sign evidence of avsim's detector near each view's sign.

    outputs: the detector's raw per-stride maps, each (B, 1 + C + 4, H_s, W_s);
    sign_boxes_xyxy_px: (B, 4) the sign's box in input pixels.
    A view with no cell near its box gets zeros (and no gradient).
    """
    preds, centres, cell_strides = flatten_outputs(outputs, strides)  # (B, N, K)
    near = cells_near_boxes(centres, sign_boxes_xyxy_px.to(preds.dtype), margin_px)
    objectness = torch.sigmoid(preds[..., 0])
    class_prob = torch.sigmoid(preds[..., 1 + STOP_CLASS_INDEX])
    score = objectness * class_prob
    heights_px = torch.exp(preds[..., -1].clamp(max=MAX_LOG_SIZE)) * cell_strides  # boxes.decode_boxes' height
    return StopEvidence(masked_max(score, near, 0.0), masked_max(objectness, near, 0.0), masked_max(class_prob, near, 0.0),
                        masked_max(preds[..., 1 + STOP_CLASS_INDEX], near, -20.0), reported_height_px(heights_px, score, near))


def soft_maximum(values: torch.Tensor, temperature: float) -> torch.Tensor:
    """A smooth maximum of (N,) values: t (logsumexp(v / t) - log N).

    It lies between the mean (t -> inf) and the maximum (t -> 0) of the values: by Jensen's
    inequality it is never below the mean it replaces, and never above the maximum.
    """
    if temperature <= 0:
        raise ValueError(f"soft maximum temperature must be > 0, got {temperature}")
    # Computed as max + t log(1 + mean(exp((v - max) / t) - 1)) with expm1 and log1p, which keeps
    # its digits when t is large and every term is near 1 (the plain form cancels there).
    top = values.amax(dim=-1, keepdim=True)
    return top.squeeze(-1) + temperature * torch.log1p(torch.expm1((values - top) / temperature).mean(dim=-1))


def soft_kth_largest(values: torch.Tensor, k: int, temperature: float) -> torch.Tensor:
    """A smooth k-th largest of the last axis of `values` (..., N): the soft maximum, over every
    k of the N, of their soft minimum; shape (...). k = 1 is `soft_maximum` itself.

    The k-th largest of N is the largest minimum over the subsets of size k, so this is what a
    k-of-N vote reports (the k-th highest confidence) made smooth: a step lowers it by working on
    the k best values together rather than on the best one alone. The subsets are enumerated,
    which suits the few members of a network ensemble (3 of them give 3 pairs).
    """
    count = values.shape[-1]
    if not 1 <= k <= count:
        raise ValueError(f"k must be in [1, {count}], got {k}")
    if k == 1:
        return soft_maximum(values, temperature)
    subsets = torch.tensor(list(itertools.combinations(range(count), k)), device=values.device)  # (C, k)
    members = values[..., subsets]  # (..., C, k)
    return soft_maximum(-soft_maximum(-members, temperature), temperature)


def gate_weight(estimate_m: torch.Tensor, trigger_dist_m: float | None, softness_m: float) -> torch.Tensor:
    """The braking gate, smooth: sigmoid((trigger - estimate) / softness), about 1 for a pinhole
    estimate inside the trigger distance and 0 beyond it; 1 everywhere with no gate (None)."""
    if trigger_dist_m is None:
        return torch.ones_like(estimate_m)
    return torch.sigmoid((trigger_dist_m - estimate_m) / softness_m)


def driveby_objective(frame_values: list[torch.Tensor], temperature: float) -> torch.Tensor:
    """Mean over sequences of the soft maximum over each sequence's frames (each (F_i,))."""
    return torch.stack([soft_maximum(values, temperature) for values in frame_values]).mean()


def kth_largest_in_windows(values: torch.Tensor, k: int, n: int) -> torch.Tensor:
    """(F,) frame values, far to near -> (max(F - n + 1, 1),): the k-th largest value in each
    window of n consecutive frames (a sequence shorter than n is one window).

    A k-of-n vote passes a window when its k-th largest frame is above the threshold, so this is
    the quantity an attack on the vote must hold down in every window; k = n = 1 gives the
    frame values themselves.
    """
    if not 1 <= k <= n:
        raise ValueError(f"a k-of-n vote needs 1 <= k <= n, got k={k}, n={n}")
    windows = values.unfold(0, n, 1) if len(values) >= n else values[None]
    return torch.topk(windows, min(k, windows.shape[1]), dim=1).values[:, -1]


def log_height_ratio(box_height_px: torch.Tensor, true_height_px: torch.Tensor) -> torch.Tensor:
    """log(predicted / true box height) per view: 0 for a true box, -0.22 for one 20 % short
    (which the pinhole estimate reads 25 % too far)."""
    return torch.log(box_height_px.clamp(min=0.5) / true_height_px)
