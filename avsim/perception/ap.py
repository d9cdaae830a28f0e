"""Detection scoring primitives: IoU, greedy matching and AP at an IoU threshold.

AP uses all-point interpolation (as in VOC 2010+): per class, detections from all images
are sorted by score, each is a true positive if it overlaps a not-yet-matched ground truth
of its class in its image (greedy, highest score first), and AP is the area under the
precision-recall curve after making precision monotonically non-increasing.
"""

from __future__ import annotations

import math

import numpy as np


def box_areas(boxes: np.ndarray) -> np.ndarray:
    """(N,) areas of (N, 4) xyxy boxes."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    return np.prod(boxes[:, 2:] - boxes[:, :2], axis=1)


def box_intersections(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) matrix of the areas where (N, 4) and (M, 4) xyxy boxes overlap."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    wh = np.clip(np.minimum(a[:, None, 2:], b[None, :, 2:]) - np.maximum(a[:, None, :2], b[None, :, :2]), 0.0, None)
    return wh[..., 0] * wh[..., 1]


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) IoU matrix of (N, 4) and (M, 4) xyxy boxes."""
    inter = box_intersections(a, b)
    return inter / np.maximum(box_areas(a)[:, None] + box_areas(b)[None, :] - inter, 1e-12)


def average_precision(scores: np.ndarray, is_tp: np.ndarray, num_gt: int) -> float:
    """All-point interpolated AP from detection scores (D,), true-positive flags (D,) and the ground-truth count.

    NaN when there is no ground truth (the class is absent from the data).
    """
    if num_gt == 0:
        return math.nan
    order = np.argsort(-np.asarray(scores, dtype=np.float64), kind="stable")
    tp = np.asarray(is_tp, dtype=np.float64)[order]
    cum_tp = np.cumsum(tp)
    recall = np.concatenate([[0.0], cum_tp / num_gt, [1.0]])
    precision = np.concatenate([[1.0], cum_tp / np.arange(1, len(tp) + 1), [0.0]])
    precision = np.maximum.accumulate(precision[::-1])[::-1]
    return float(np.sum((recall[1:] - recall[:-1]) * precision[1:]))


def match_detections(det_boxes: np.ndarray, det_scores: np.ndarray, gt_boxes: np.ndarray,
                     iou_threshold: float = 0.5) -> np.ndarray:
    """True-positive flags (D,) for one image and one class, greedy by descending score."""
    is_tp = np.zeros(len(det_boxes), dtype=bool)
    if len(det_boxes) == 0 or len(gt_boxes) == 0:
        return is_tp
    ious = box_iou(det_boxes, gt_boxes)
    taken = np.zeros(len(gt_boxes), dtype=bool)
    for d in np.argsort(-det_scores, kind="stable"):
        candidates = np.where(taken, -1.0, ious[d])
        best = int(np.argmax(candidates))
        if candidates[best] >= iou_threshold:
            taken[best] = True
            is_tp[d] = True
    return is_tp


def mean_ap(aps: dict[str, float]) -> float:
    """Mean over classes that have ground truth (NaN if none has)."""
    values = [v for v in aps.values() if not math.isnan(v)]
    return float(np.mean(values)) if values else math.nan
