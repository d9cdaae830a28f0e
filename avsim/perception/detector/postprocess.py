"""Raw network maps -> scored boxes, with class-aware NMS by OpenCV.

score = sigmoid(objectness) * sigmoid(best class logit); one class per cell (signs are
mutually exclusive). Boxes are in input pixels; map them to the image with
`Letterbox.to_image`.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch

from avsim.perception.detector.boxes import decode_boxes, flatten_outputs
from avsim.perception.detector.model import STRIDES

IOU_THRESHOLD = 0.5
MAX_DETECTIONS = 100
PRE_NMS_TOP_K = 1000


def nms(boxes_xyxy: np.ndarray | torch.Tensor, scores: np.ndarray | torch.Tensor, classes: np.ndarray | torch.Tensor,
        iou_threshold: float = IOU_THRESHOLD) -> np.ndarray:
    """Class-aware non-maximum suppression with `cv2.dnn.NMSBoxesBatched`.

    boxes_xyxy: (N, 4) x0, y0, x1, y1 [px]; scores: (N,); classes: (N,) ints.
    A box is dropped when a higher-scored box of the same class overlaps it with
    IoU > iou_threshold; boxes of different classes never suppress each other.
    Returns the kept indices (K,) int64, highest score first.
    """
    boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    scores_np = np.asarray(scores, dtype=np.float32).reshape(-1)
    classes_np = np.asarray(classes, dtype=np.int32).reshape(-1)
    if not len(boxes) == len(scores_np) == len(classes_np):
        raise ValueError(f"nms needs as many boxes, scores and classes, got {len(boxes)}, {len(scores_np)}, {len(classes_np)}")
    if len(boxes) == 0:
        return np.zeros(0, dtype=np.int64)
    xywh = np.concatenate([boxes[:, :2], boxes[:, 2:] - boxes[:, :2]], axis=1)  # OpenCV wants x, y, w, h
    keep = np.asarray(cv2.dnn.NMSBoxesBatched(xywh, scores_np, classes_np, float(scores_np.min()) - 1.0,
                                              float(iou_threshold)), dtype=np.int64).reshape(-1)
    return keep[np.argsort(-scores_np[keep], kind="stable")]


def decode(outputs: list[torch.Tensor], conf_threshold: float, strides: tuple[int, ...] = STRIDES,
           iou_threshold: float = IOU_THRESHOLD, max_detections: int = MAX_DETECTIONS,
           pre_nms_top_k: int = PRE_NMS_TOP_K, origin_px: tuple[int, int] = (0, 0),
           region_px: tuple[float, float, float, float] | None = None) -> list[torch.Tensor]:
    """Detections per image after score threshold and NMS.

    outputs: the model's per-stride maps, each (B, 1 + C + 4, H_s, W_s).
    origin_px: where the maps' input starts in the input frame [px]: (0, 0) for a whole
    input, a crop's corner for a crop (`roi`). Boxes come out in the frame's pixels, computed
    exactly as the whole frame's cells would be.
    region_px: if given, (x0, y0, x1, y1) [frame px]: only cells whose centres lie inside it
    may become detections.
    Returns B tensors (D, 6): x0, y0, x1, y1 [frame px], score, class index; score-sorted,
    D <= max_detections. Only the `pre_nms_top_k` best cells above `conf_threshold` enter NMS.
    """
    preds, centres, cell_strides = flatten_outputs([o.detach().float().cpu() for o in outputs], strides)
    if origin_px != (0, 0):
        centres = centres + torch.tensor(origin_px, dtype=centres.dtype)  # integers: exact in float32
    candidate = torch.ones(centres.shape[0], dtype=torch.bool)
    if region_px is not None:
        x0, y0, x1, y1 = region_px
        candidate = (centres[:, 0] >= x0) & (centres[:, 0] < x1) & (centres[:, 1] >= y0) & (centres[:, 1] < y1)
    num_classes = preds.shape[-1] - 5
    class_prob, class_idx = torch.sigmoid(preds[..., 1:1 + num_classes]).max(dim=-1)
    scores = torch.sigmoid(preds[..., 0]) * class_prob  # (B, N)
    results = []
    for b in range(preds.shape[0]):
        cells = torch.nonzero((scores[b] > conf_threshold) & candidate).squeeze(1)
        if cells.numel() > pre_nms_top_k:
            cells = cells[torch.topk(scores[b, cells], pre_nms_top_k).indices]
        boxes = decode_boxes(preds[b, cells, 1 + num_classes:], centres[cells], cell_strides[cells])
        keep = torch.from_numpy(nms(boxes.numpy(), scores[b, cells].numpy(), class_idx[b, cells].numpy(), iou_threshold))
        keep = keep[:max_detections]
        results.append(torch.cat([boxes[keep], scores[b, cells[keep], None], class_idx[b, cells[keep], None].float()], dim=1))
    return results
