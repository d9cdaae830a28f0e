"""A Darknet YOLO in bfloat16 for inference: `perception.yolo_precision = "bf16"`.

A copy of the float32 network with weights and activations in bfloat16 (oneDNN's bf16
convolutions on AVX-512 BF16, summing in float32, rounding each layer's output to 8
significant bits). The heads' raw maps are decoded in float32, so only the network's
arithmetic differs from the float32 model, which stays as it is for the OpenCV reference
check and for attacks (they differentiate `YoloModel`). How far the scores move is measured,
not assumed (docs/yolo.md;
`python -m avsim.perception.coco.realism --network yolo --precisions fp32,bf16`).
"""

from __future__ import annotations

import copy

import torch
from torch import nn

from avsim.perception.cpu_bf16 import require_bf16
from avsim.perception.yolo.decode import decode_heads, score_rows
from avsim.perception.yolo.model import PIXEL_SCALE, YoloModel


class Bf16Yolo(nn.Module):
    """`detect(images, min_score)` as `YoloModel.detect`, computed in bfloat16. Inference only."""

    def __init__(self, model: YoloModel) -> None:
        super().__init__()
        require_bf16("perception.yolo_precision")
        self.network = copy.deepcopy(model.network).to(torch.bfloat16).eval()
        for head, original in zip(self.network.heads, model.network.heads, strict=True):
            head.anchors_px = original.anchors_px.clone()  # float32: bf16 would round an anchor of 319 px to 320
        self.class_names = model.class_names
        self.input_size_px = model.input_size_px
        self.size_multiple_px = model.size_multiple_px

    def detect(self, images: torch.Tensor, min_score: float) -> torch.Tensor:
        """(1, 3, H, W) float RGB 0-255 -> (1, n, 6) float32 rows, as `YoloModel.detect`."""
        raws = self.network((images * PIXEL_SCALE).to(torch.bfloat16))
        decoded = decode_heads([raw.float() for raw in raws], self.network.heads, tuple(images.shape[-2:]))
        return score_rows(decoded, min_score)[None]
