"""Run the COCO CenterNet on camera images: RGB frame -> list[Detection] in image pixels.

Per frame: the input (`preprocess`, by `perception.coco_input`) -> the network and the
graph's own decoding (100 peaks) under `torch.inference_mode()` -> peaks at or above
`min_confidence` -> boxes mapped back to the image and clipped to it -> with a region of
interest, only boxes centred inside it -> class-aware NMS (OpenCV, IoU 0.5; CenterNet's
3x3 peak extraction leaves a few duplicate boxes of one object on neighbouring cells).
"""

from __future__ import annotations

import numpy as np
import torch

from avsim.perception.base import Detection, touches_border
from avsim.perception.coco.bf16 import Bf16CenterNet
from avsim.perception.coco.labels import AVSIM_CLASS_NAMES
from avsim.perception.coco.model import CocoCenterNet
from avsim.perception.coco.preprocess import COCO_INPUTS, Region, image_tensor, network_input
from avsim.perception.detector.letterbox import check_image
from avsim.perception.detector.postprocess import IOU_THRESHOLD, nms


class CocoRunner:
    """`detect(image, camera, region_px)`: that frame's COCO objects, highest confidence first."""

    def __init__(self, model: CocoCenterNet | Bf16CenterNet, input_mode: str, upscale: float, min_confidence: float,
                 iou_threshold: float = IOU_THRESHOLD) -> None:
        if input_mode not in COCO_INPUTS:
            raise ValueError(f"unknown COCO input mode {input_mode!r}; choose one of: {', '.join(COCO_INPUTS)}")
        self.model = model
        self.input_mode = input_mode
        self.upscale = upscale
        self.min_confidence = min_confidence
        self.iou_threshold = iou_threshold

    def raw_detections(self, image_rgb: np.ndarray, region_px: Region | None = None,
                       min_score: float | None = None) -> np.ndarray:
        """(D, 6) float64: x1, y1, x2, y2 [image px, unclipped], score, class id: the graph's k
        peaks, or those scoring at least `min_score`."""
        check_image(image_rgb)
        with torch.inference_mode():
            x, window = network_input(image_tensor(image_rgb), self.input_mode, region_px, self.upscale)
            det = self.model.detect(x, min_score)[0].double().numpy()
        det[:, :4] = window.to_image(det[:, :4])
        return det

    def detect(self, image_rgb: np.ndarray, camera: str, region_px: Region | None = None) -> list[Detection]:
        """Detections in one (H, W, 3) uint8 RGB image; boxes in image pixels, clipped to it.

        region_px: (x0, y0, x1, y1) [px]: only boxes whose centre lies inside are reported;
        with `crop` and `upscale` the network also sees only this region.
        """
        image_h, image_w = image_rgb.shape[:2]
        det = self.raw_detections(image_rgb, region_px, self.min_confidence)
        det[:, :4] = np.clip(det[:, :4], 0.0, [image_w, image_h, image_w, image_h])
        if region_px is not None:
            x0, y0, x1, y1 = region_px
            cx, cy = (det[:, 0] + det[:, 2]) / 2, (det[:, 1] + det[:, 3]) / 2
            det = det[(cx >= x0) & (cx < x1) & (cy >= y0) & (cy < y1)]
        det = det[nms(det[:, :4], det[:, 4], det[:, 5].astype(np.int32), self.iou_threshold)]
        detections = []
        for x0, y0, x1, y1, score, cls in det:
            box = (float(x0), float(y0), float(x1), float(y1))
            detections.append(Detection(AVSIM_CLASS_NAMES[int(cls)], float(score), box, camera,
                                        touches_border(box, image_w, image_h)))
        return detections
