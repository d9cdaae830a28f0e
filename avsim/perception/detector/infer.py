"""Run trained detector weights on camera images: RGB frame -> list[Detection].

Per frame: letterbox (identity for 640x480 at the deployed size) -> fused network in
channels-last memory under `torch.inference_mode()` -> decode + OpenCV NMS -> boxes mapped
back to image pixels and clipped to the image. With a region of interest, the network runs
on a crop around it (`roi`) and only the region's cells are decoded. Uses min(2, cpu count)
torch threads (a process-wide torch setting; pass num_threads=1 when another busy process
shares the two cores: then one thread is faster, see `model`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from avsim.perception.base import Detection, touches_border
from avsim.perception.detector.letterbox import Letterbox, check_image, fit, letterbox, to_tensor, warp
from avsim.perception.detector.postprocess import IOU_THRESHOLD, MAX_DETECTIONS, decode
from avsim.perception.detector.roi import clip_region, crop_for
from avsim.perception.detector.weights import load_weights

DEFAULT_CONF_THRESHOLD = 0.3


class SignDetectorRunner:
    """Loads weights once; `detect(image, camera)` returns that frame's signs, highest confidence first."""

    def __init__(self, weights_path: str | Path, conf_threshold: float = DEFAULT_CONF_THRESHOLD,
                 iou_threshold: float = IOU_THRESHOLD, max_detections: int = MAX_DETECTIONS,
                 num_threads: int | None = None) -> None:
        torch.set_num_threads(num_threads if num_threads is not None else max(1, min(2, os.cpu_count() or 1)))
        model, self.meta = load_weights(weights_path)
        self.model = model.fuse().to(memory_format=torch.channels_last)
        self.input_size = (int(self.meta["input_size"][0]), int(self.meta["input_size"][1]))
        self.class_names = tuple(self.meta["class_names"])
        self.conf_threshold = conf_threshold
        self.iou_threshold = iou_threshold
        self.max_detections = max_detections

    def _to_detections(self, det: torch.Tensor, box: Letterbox, image_w: int, image_h: int, camera: str) -> list[Detection]:
        det = det.numpy()
        boxes = np.clip(box.to_image(det[:, :4]), 0.0, [image_w, image_h, image_w, image_h])
        out = []
        for (x0, y0, x1, y1), score, cls in zip(boxes, det[:, 4], det[:, 5]):
            xyxy = (float(x0), float(y0), float(x1), float(y1))
            out.append(Detection(self.class_names[int(cls)], float(score), xyxy, camera, touches_border(xyxy, image_w, image_h)))
        return out

    def detect_batch(self, images_rgb: list[np.ndarray], camera: str = "front",
                     conf_threshold: float | None = None) -> list[list[Detection]]:
        """One list of detections per (H, W, 3) uint8 RGB image (sizes may differ), each sorted by confidence."""
        if not images_rgb:
            return []
        letterboxed = [letterbox(image, self.input_size) for image in images_rgb]
        batch = torch.stack([tensor for tensor, _ in letterboxed]).contiguous(memory_format=torch.channels_last)
        threshold = self.conf_threshold if conf_threshold is None else conf_threshold
        with torch.inference_mode():
            detections = decode(self.model(batch), threshold, self.model.strides, self.iou_threshold, self.max_detections)
        return [self._to_detections(det, box, image.shape[1], image.shape[0], camera)
                for det, (_, box), image in zip(detections, letterboxed, images_rgb)]

    def detect(self, image_rgb: np.ndarray, camera: str, conf_threshold: float | None = None,
               region_px: tuple[int, int, int, int] | None = None) -> list[Detection]:
        """Detections in one (H, W, 3) uint8 RGB image, highest confidence first; boxes in image pixels.

        region_px: if given, (x0, y0, x1, y1) [image px]: only boxes whose network cells are
        centred inside it are reported. When the image is the network's own input size, the
        network then runs on a crop around the region only (`roi.crop_for`), with the same
        scores and boxes as on the whole image, bit for bit.
        """
        check_image(image_rgb)
        image_h, image_w = image_rgb.shape[:2]
        box = fit(image_w, image_h, self.input_size)
        crop = crop_for(region_px, image_w, image_h) if region_px is not None and box.is_identity(image_w, image_h) else None
        if crop is not None:
            x0, y0, x1, y1 = crop
            tensor, origin = to_tensor(image_rgb[y0:y1, x0:x1]), (x0, y0)
            region_in = tuple(float(v) for v in clip_region(region_px, image_w, image_h))
        else:
            tensor, origin = to_tensor(warp(image_rgb, box)), (0, 0)
            region_in = None if region_px is None else tuple(box.to_input(np.array(clip_region(region_px, image_w, image_h)))[0])
        threshold = self.conf_threshold if conf_threshold is None else conf_threshold
        with torch.inference_mode():
            det = decode(self.model(tensor.unsqueeze(0)), threshold, self.model.strides, self.iou_threshold,
                         self.max_detections, origin_px=origin, region_px=region_in)[0]
        return self._to_detections(det, box, image_w, image_h, camera)
