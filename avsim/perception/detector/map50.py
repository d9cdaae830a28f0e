"""Quick validation metric during training: per-class AP at IoU 0.5 on letterboxed inputs.

The full report on camera images (recall by distance, false positives, pinhole error)
is `avsim.perception.evaluation`; both score with `avsim.perception.ap`.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.utils.data import DataLoader, Dataset

from avsim.perception.ap import average_precision, match_detections
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.data import collate
from avsim.perception.detector.postprocess import decode

EVAL_CONF_THRESHOLD = 0.001


@torch.no_grad()
def evaluate_map50(model: nn.Module, dataset: Dataset, batch_size: int = 8, class_names: tuple[str, ...] = SIGN_CLASSES,
                   conf_threshold: float = EVAL_CONF_THRESHOLD, iou_threshold: float = 0.5,
                   device: str | torch.device = "cpu") -> dict[str, float]:
    """{class name: AP@0.5} of `model` on `dataset` (items as `data.SignDataset`, no augmentation)."""
    was_training = model.training
    model.eval()
    per_class: dict[int, tuple[list[np.ndarray], list[np.ndarray]]] = {c: ([], []) for c in range(len(class_names))}
    num_gt = dict.fromkeys(range(len(class_names)), 0)
    try:
        for images, targets in DataLoader(dataset, batch_size=batch_size, shuffle=False, collate_fn=collate):
            detections = decode(model(images.to(device)), conf_threshold)
            for det, target in zip(detections, targets):
                det = det.numpy()
                gt_boxes, gt_classes = target["boxes"].numpy(), target["classes"].numpy()
                for c in range(len(class_names)):
                    mine = det[det[:, 5] == c]
                    gt_c = gt_boxes[gt_classes == c]
                    num_gt[c] += len(gt_c)
                    per_class[c][0].append(mine[:, 4])
                    per_class[c][1].append(match_detections(mine[:, :4], mine[:, 4], gt_c, iou_threshold))
    finally:
        model.train(was_training)
    return {name: average_precision(np.concatenate(per_class[c][0]) if per_class[c][0] else np.zeros(0),
                                    np.concatenate(per_class[c][1]) if per_class[c][1] else np.zeros(0, bool), num_gt[c])
            for c, name in enumerate(class_names)}
