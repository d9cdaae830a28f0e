"""Run trained detector weights on camera images: RGB frame -> list[Detection].

Per frame: letterbox (identity for 640x480 at the deployed size) -> fused network in
channels-last memory under `torch.inference_mode()` -> decode + OpenCV NMS -> boxes mapped
back to image pixels and clipped to the image. With a region of interest, the network runs
on a crop around it (`roi`) and only the region's cells are decoded. Uses min(2, cpu count)
torch threads (a process-wide torch setting; `import avsim` shortens libgomp's busy-wait so that
two threads beside another busy process do not spin, docs/performance.md).

Precision: "fp32", or "bf16", where the convolutions run under bfloat16 autocast (oneDNN's
AVX-512 BF16 dot products, summing in float32; the maps are decoded in float32). bf16 scores
differ from fp32's by bf16 rounding (`avsim.perception.detector.precision_agreement` measures by
how much).

Batches (`detect_many`, the lock-step batch of `avsim.lockstep`): a frame's
detections must not depend on which other frames share its network call. Measured with the
shipped weights at 1 thread on the front crop: under bf16 every image's maps are the same, bit
for bit, at every batch size from 1 to 8; under fp32 oneDNN picks another kernel for a batch of
one than for two or more, which changes the last bits. So fp32 runs each frame alone, exactly
as a lone run does, and only bf16 frames share a call. `tests/perception/detector/test_batch_invariance.py`
checks both on this machine.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from avsim.config import DETECTOR_PRECISIONS
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
                 num_threads: int | None = None, precision: str = "fp32") -> None:
        if precision not in DETECTOR_PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(DETECTOR_PRECISIONS)}, got {precision!r}")
        self.precision = precision
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
            detections = decode(self._maps(batch), threshold, self.model.strides, self.iou_threshold, self.max_detections)
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
        return self.detect_many([(image_rgb, camera, region_px)], conf_threshold)[0]

    def pixels_needed(self, region_px: tuple[int, int, int, int] | None, width_px: int, height_px: int) -> tuple[int, int, int, int] | None:
        """The part (x0, y0, x1, y1) [px] of a W x H frame that `detect(..., region_px=region_px)` reads:
        the region's crop (`roi.crop_for`), or None when it reads the whole frame."""
        if region_px is None or not fit(width_px, height_px, self.input_size).is_identity(width_px, height_px):
            return None
        return crop_for(region_px, width_px, height_px)

    def detect_many(self, frames: list[tuple[np.ndarray, str, tuple[int, int, int, int] | None]],
                    conf_threshold: float | None = None) -> list[list[Detection]]:
        """`detect` over many (image_rgb, camera, region_px) frames at once, one list of detections each.

        Each frame's detections are what `detect` gives it alone, bit for bit (see the module
        docstring on batches): under bf16, frames whose network inputs have the same shape share
        one network call; under fp32 each frame has a call of its own.
        """
        threshold = self.conf_threshold if conf_threshold is None else conf_threshold
        prepared = [self._prepare(image, region) for image, _, region in frames]
        groups: dict[tuple[int, ...], list[int]] = {}
        for index, (pixels, _, _, _) in enumerate(prepared):
            key = pixels.shape if self.precision == "bf16" else (index,)
            groups.setdefault(key, []).append(index)
        out: list[list[Detection]] = [[] for _ in frames]
        with torch.inference_mode():
            for indices in groups.values():
                maps = self._maps(_input_batch([prepared[i][0] for i in indices]))
                for row, i in enumerate(indices):
                    _, box, origin, region_in = prepared[i]
                    det = decode([m[row:row + 1] for m in maps], threshold, self.model.strides, self.iou_threshold,
                                 self.max_detections, origin_px=origin, region_px=region_in)[0]
                    image, camera, _ = frames[i]
                    out[i] = self._to_detections(det, box, image.shape[1], image.shape[0], camera)
        return out

    def _prepare(self, image_rgb: np.ndarray, region_px: tuple[int, int, int, int] | None
                 ) -> tuple[np.ndarray, Letterbox, tuple[int, int], tuple[float, float, float, float] | None]:
        """(network input pixels (H_in, W_in, 3) uint8, letterbox, origin of the input in the frame [px],
        region in frame px)."""
        check_image(image_rgb)
        image_h, image_w = image_rgb.shape[:2]
        box = fit(image_w, image_h, self.input_size)
        crop = self.pixels_needed(region_px, image_w, image_h)
        if crop is not None:
            x0, y0, x1, y1 = crop
            region_in = tuple(float(v) for v in clip_region(region_px, image_w, image_h))
            return image_rgb[y0:y1, x0:x1], box, (x0, y0), region_in
        region_in = None if region_px is None else tuple(box.to_input(np.array(clip_region(region_px, image_w, image_h)))[0])
        return warp(image_rgb, box), box, (0, 0), region_in

    def _maps(self, batch: torch.Tensor) -> list[torch.Tensor]:
        """The network's per-stride maps for a (B, 3, H_in, W_in) batch, at this runner's precision."""
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.precision == "bf16"):
            return self.model(batch)


def _input_batch(inputs: list[np.ndarray]) -> torch.Tensor:
    """(B, 3, H_in, W_in) float32 in [0, 1], channels-last, from B (H_in, W_in, 3) uint8 inputs: the
    values `to_tensor` gives each. One input becomes `to_tensor`'s own tensor, as a lone frame's
    always has; more are stacked as uint8 first, which costs far less than stacking float tensors."""
    if len(inputs) == 1:
        return to_tensor(inputs[0]).unsqueeze(0)
    return torch.from_numpy(np.stack(inputs)).permute(0, 3, 1, 2).float().mul_(1.0 / 255.0)
