"""Run trained detector weights on camera images: RGB frame -> list[Detection].

Per frame: letterbox (identity for 640x480 at the deployed size) -> fused network in
channels-last memory under `torch.inference_mode()` -> decode + OpenCV NMS -> boxes mapped
back to image pixels and clipped to the image. With a region of interest, the network runs
on a crop around it (`roi`) and only the region's cells are decoded. Uses min(2, cpu count)
torch threads (a process-wide torch setting; `import avsim` shortens libgomp's busy-wait so that
two threads beside another busy process do not spin, docs/performance.md).

Frames larger than the network's input (a camera preset beyond the study's 640x480): the frame is
letterboxed down to the input, as the network was trained, which shrinks a 1920x1080 frame 3x and
costs the far signs their pixels. With `native_pixels` the runner also searches the region at the
frame's own pixels (the network is fully convolutional; the crop is `roi.crop_for`'s, or the whole
frame padded to a multiple of 32), and merges both passes' boxes by class-aware NMS. The native pass
finds the far signs; the letterboxed pass keeps the near ones, which at the frame's own pixels are
larger than any sign in the training frames. A frame at the input size is searched once, as before.

Precision: "fp32", or "bf16", where a copy of the network with its weights in bfloat16 runs on
bfloat16 input (oneDNN's AVX-512 BF16 dot products, summing in float32 and rounding each layer's
output to bf16; the maps are decoded in float32), or "auto", which
is bf16 where oneDNN runs it on this CPU and fp32 elsewhere (`cpu_bf16.detector_arithmetic`). bf16 scores
differ from fp32's by bf16 rounding (`avsim.perception.detector.precision_agreement` measures by
how much). The bf16 copy computes what bfloat16 autocast on the float32 network computes, bit for bit
(autocast rounds the same weights, biases and inputs to bf16 before each convolution, and every other
layer here runs on its bf16 outputs either way; `tests/perception/detector/test_detector_infer.py` checks it),
without casting the weights again on every call: 7.1 against 7.8 ms a front crop at 1 thread.

Batches (`detect_many`, the lock-step batch of `avsim.lockstep`): a frame's
detections must not depend on which other frames share its network call. Measured with the
shipped weights at 1 thread on the front crop: under bf16 every image's maps are the same, bit
for bit, at every batch size from 1 to 8; under fp32 oneDNN picks another kernel for a batch of
one than for two or more, which changes the last bits. So fp32 runs each frame alone, exactly
as a lone run does, and only bf16 frames share a call. `tests/perception/detector/test_batch_invariance.py`
checks both on this machine.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from avsim.perception.base import Detection, touches_border
from avsim.perception.cpu_bf16 import detector_arithmetic
from avsim.perception.detector.letterbox import Letterbox, check_image, fit, to_tensor, warp
from avsim.perception.detector.postprocess import IOU_THRESHOLD, MAX_DETECTIONS, decode, nms
from avsim.perception.detector.roi import ALIGN_PX, clip_region, crop_for
from avsim.perception.detector.weights import load_weights

DEFAULT_CONF_THRESHOLD = 0.3


class _Pass(NamedTuple):
    """One network input made from a frame: its pixels (H_in, W_in, 3) uint8; the letterbox that maps the
    decoded boxes back to the frame; where the input starts in the letterboxed frame [px] (a crop's corner,
    else (0, 0)); and the region in the letterboxed frame's pixels (None: no region)."""

    pixels: np.ndarray
    box: Letterbox
    origin_px: tuple[int, int]
    region_in: tuple[float, float, float, float] | None


class SignDetectorRunner:
    """Loads weights once; `detect(image, camera)` returns that frame's signs, highest confidence first."""

    def __init__(self, weights_path: str | Path, conf_threshold: float = DEFAULT_CONF_THRESHOLD,
                 iou_threshold: float = IOU_THRESHOLD, max_detections: int = MAX_DETECTIONS,
                 num_threads: int | None = None, precision: str = "fp32", native_pixels: bool = False) -> None:
        self.precision = detector_arithmetic(precision)
        self.native_pixels = native_pixels
        torch.set_num_threads(num_threads if num_threads is not None else max(1, min(2, os.cpu_count() or 1)))
        model, self.meta = load_weights(weights_path)
        self.model = model.fuse().to(memory_format=torch.channels_last)
        # What `_maps` runs under bf16: a copy of the network in bfloat16 (the module docstring).
        self._bf16_model = copy.deepcopy(self.model).to(torch.bfloat16) if self.precision == "bf16" else None
        self.input_size = (int(self.meta["input_size"][0]), int(self.meta["input_size"][1]))
        self.class_names = tuple(self.meta["class_names"])
        self.conf_threshold = conf_threshold
        self.iou_threshold = iou_threshold
        self.max_detections = max_detections

    def _to_detections(self, det: np.ndarray, image_w: int, image_h: int, camera: str) -> list[Detection]:
        """(D, 6) detections [frame px, score, class] -> Detections, boxes clipped to the frame."""
        boxes = np.clip(det[:, :4], 0.0, [image_w, image_h, image_w, image_h])
        out = []
        for (x0, y0, x1, y1), score, cls in zip(boxes, det[:, 4], det[:, 5]):
            xyxy = (float(x0), float(y0), float(x1), float(y1))
            out.append(Detection(self.class_names[int(cls)], float(score), xyxy, camera, touches_border(xyxy, image_w, image_h)))
        return out

    def detect_batch(self, images_rgb: list[np.ndarray], camera: str = "front",
                     conf_threshold: float | None = None) -> list[list[Detection]]:
        """One list of detections per (H, W, 3) uint8 RGB image (sizes may differ), each sorted by confidence:
        each whole image searched as `detect` searches it (`detect_many` with no region)."""
        return self.detect_many([(image, camera, None) for image in images_rgb], conf_threshold)

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
        passes = [(frame_index, one_pass) for frame_index, (image, _, region) in enumerate(frames)
                  for one_pass in self._passes(image, region)]
        groups: dict[tuple[int, ...], list[int]] = {}
        for index, (_, one_pass) in enumerate(passes):
            key = one_pass.pixels.shape if self.precision == "bf16" else (index,)
            groups.setdefault(key, []).append(index)
        boxes_by_frame: list[list[np.ndarray]] = [[] for _ in frames]  # per pass: (D, 6) in frame px
        with torch.inference_mode():
            for indices in groups.values():
                maps = self._maps(_input_batch([passes[i][1].pixels for i in indices]))
                for row, i in enumerate(indices):
                    frame_index, one_pass = passes[i]
                    det = decode([m[row:row + 1] for m in maps], threshold, self.model.strides, self.iou_threshold,
                                 self.max_detections, origin_px=one_pass.origin_px, region_px=one_pass.region_in)[0]
                    boxes_by_frame[frame_index].append(_in_frame(det, one_pass.box))
        return [self._to_detections(self._merge(found), image.shape[1], image.shape[0], camera)
                for found, (image, camera, _) in zip(boxes_by_frame, frames)]

    def _merge(self, per_pass: list[np.ndarray]) -> np.ndarray:
        """One frame's (D, 6) detections [frame px, score, class] from its passes: a lone pass as it is,
        two passes by class-aware NMS over both, best first, at most `max_detections`."""
        if len(per_pass) == 1:
            return per_pass[0]
        both = np.concatenate(per_pass)
        keep = nms(both[:, :4], both[:, 4], both[:, 5].astype(np.int64), self.iou_threshold)[:self.max_detections]
        return both[keep]

    def _passes(self, image_rgb: np.ndarray, region_px: tuple[int, int, int, int] | None) -> list[_Pass]:
        """The network inputs one frame needs: the letterboxed frame (or, at the input size, the region's
        exact crop), and with `native_pixels` a frame larger than the input also at its own pixels."""
        check_image(image_rgb)
        image_h, image_w = image_rgb.shape[:2]
        box = fit(image_w, image_h, self.input_size)
        crop = self.pixels_needed(region_px, image_w, image_h)
        if crop is not None:
            return [_crop_pass(image_rgb, crop, region_px)]
        region_in = None if region_px is None else tuple(box.to_input(np.array(clip_region(region_px, image_w, image_h)))[0])
        passes = [_Pass(warp(image_rgb, box), box, (0, 0), region_in)]
        if self.native_pixels and box.scale < 1.0:
            passes.append(_native_pass(image_rgb, region_px))
        return passes

    def _maps(self, batch: torch.Tensor) -> list[torch.Tensor]:
        """The network's per-stride maps for a (B, 3, H_in, W_in) batch, at this runner's precision."""
        if self._bf16_model is not None:
            return self._bf16_model(batch.to(torch.bfloat16))
        return self.model(batch)


def _input_batch(inputs: list[np.ndarray]) -> torch.Tensor:
    """(B, 3, H_in, W_in) float32 in [0, 1], channels-last, from B (H_in, W_in, 3) uint8 inputs: the
    values `to_tensor` gives each. One input becomes `to_tensor`'s own tensor, as a lone frame's
    always has; more are stacked as uint8 first, which costs far less than stacking float tensors."""
    if len(inputs) == 1:
        return to_tensor(inputs[0]).unsqueeze(0)
    return torch.from_numpy(np.stack(inputs)).permute(0, 3, 1, 2).float().mul_(1.0 / 255.0)


def _in_frame(det: torch.Tensor, box: Letterbox) -> np.ndarray:
    """(D, 6) decoded detections in input px -> float64 numpy in frame px (scores and classes kept)."""
    out = det.numpy().astype(np.float64)
    out[:, :4] = box.to_image(out[:, :4])
    return out


def _crop_pass(image_rgb: np.ndarray, crop: tuple[int, int, int, int], region_px: tuple[int, int, int, int]) -> _Pass:
    """The frame's own pixels inside `crop` (`roi.crop_for`), decoded in frame px and kept to the region."""
    image_h, image_w = image_rgb.shape[:2]
    x0, y0, x1, y1 = crop
    region_in = tuple(float(v) for v in clip_region(region_px, image_w, image_h))
    return _Pass(image_rgb[y0:y1, x0:x1], Letterbox(1.0, 0.0, 0.0, x1 - x0, y1 - y0), (x0, y0), region_in)


def _native_pass(image_rgb: np.ndarray, region_px: tuple[int, int, int, int] | None) -> _Pass:
    """A frame larger than the network's input, searched at its own pixels: the region's exact crop where
    `roi.crop_for` gives one, else the whole frame with grey added below and right up to a multiple of 32."""
    image_h, image_w = image_rgb.shape[:2]
    crop = None if region_px is None else crop_for(region_px, image_w, image_h)
    if crop is not None:
        return _crop_pass(image_rgb, crop, region_px)
    padded = Letterbox(1.0, 0.0, 0.0, -(-image_w // ALIGN_PX) * ALIGN_PX, -(-image_h // ALIGN_PX) * ALIGN_PX)
    region_in = None if region_px is None else tuple(float(v) for v in clip_region(region_px, image_w, image_h))
    return _Pass(warp(image_rgb, padded), padded, (0, 0), region_in)
