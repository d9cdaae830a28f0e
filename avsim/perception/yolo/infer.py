"""Run a Darknet YOLO on camera images: RGB frame -> list[Detection] in image pixels.

Per frame: the input (`preprocess`, by `perception.yolo_input`) -> the network and its
`[yolo]` decoding under `torch.inference_mode()` -> every (box, class) scoring at least
`min_confidence` (objectness x class probability, as Darknet thresholds) -> boxes mapped back
to the image and clipped to it -> with a region of interest, only boxes centred inside it ->
class-aware NMS at IoU 0.45 (Darknet's own default for its detector demos; `nms`).
"""

from __future__ import annotations

import numpy as np
import torch

from avsim.perception.base import Detection, touches_border
from avsim.perception.coco.preprocess import Region, image_tensor
from avsim.perception.detector.letterbox import check_image
from avsim.perception.yolo.bf16 import Bf16Yolo
from avsim.perception.yolo.model import YoloModel
from avsim.perception.yolo.nms import batched_nms
from avsim.perception.yolo.preprocess import network_input

NMS_IOU = 0.45
COCO_STOP_SIGN = "stop sign"


def avsim_class_name(name: str) -> str:
    """COCO's "stop sign" is the `stop_sign` avsim's policies act on; other names stay as they are."""
    return "stop_sign" if name == COCO_STOP_SIGN else name


class YoloRunner:
    """`detect(image, camera, region_px)`: that frame's objects, highest confidence first."""

    def __init__(self, model: YoloModel | Bf16Yolo, input_mode: str, upscale: float, min_confidence: float,
                 iou_threshold: float = NMS_IOU) -> None:
        self.model = model
        self.input_mode = input_mode
        self.upscale = upscale
        self.min_confidence = min_confidence
        self.iou_threshold = iou_threshold
        self.class_names = tuple(avsim_class_name(name) for name in model.class_names)

    def raw_detections(self, image_rgb: np.ndarray, region_px: Region | None = None,
                       min_score: float | None = None) -> torch.Tensor:
        """(D, 6) float64: x1, y1, x2, y2 [image px, unclipped], score, class id of every (box, class)
        scoring at least `min_score` (default min_confidence), before NMS, highest first."""
        check_image(image_rgb)
        with torch.inference_mode():
            x, window = network_input(image_tensor(image_rgb), self.input_mode, self.model.input_size_px,
                                      self.model.size_multiple_px, region_px, self.upscale)
            det = self.model.detect(x, self.min_confidence if min_score is None else min_score)[0]
        return torch.cat([torch.from_numpy(window.to_image(det[:, :4].numpy())), det[:, 4:].double()], dim=1)

    def detect(self, image_rgb: np.ndarray, camera: str, region_px: Region | None = None) -> list[Detection]:
        """Detections in one (H, W, 3) uint8 RGB image; boxes in image pixels, clipped to it.

        region_px: (x0, y0, x1, y1) [px]: only boxes whose centre lies inside are reported;
        with `crop` and `upscale` the network also sees only this region.
        """
        image_h, image_w = image_rgb.shape[:2]
        det = self.raw_detections(image_rgb, region_px)
        det[:, :4] = torch.minimum(det[:, :4].clamp(min=0.0), torch.tensor([image_w, image_h, image_w, image_h],
                                                                             dtype=det.dtype))
        if region_px is not None:
            x0, y0, x1, y1 = region_px
            cx, cy = (det[:, 0] + det[:, 2]) / 2, (det[:, 1] + det[:, 3]) / 2
            det = det[(cx >= x0) & (cx < x1) & (cy >= y0) & (cy < y1)]
        det = det[batched_nms(det[:, :4], det[:, 4], det[:, 5].long(), self.iou_threshold)]
        detections = []
        for x0, y0, x1, y1, score, cls in det.tolist():
            box = (x0, y0, x1, y1)
            detections.append(Detection(self.class_names[int(cls)], score, box, camera, touches_border(box, image_w, image_h)))
        return detections
