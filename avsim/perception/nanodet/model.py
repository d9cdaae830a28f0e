"""NanoDet's head decoded into scored boxes: the interface `YoloRunner` runs a network through.

Legacy NanoDet's GFL head gives, per feature-map cell and class, a score (after the sigmoid), and per
box side (left, top, right, bottom) logits over 11 distance bins. As NanoDet decodes them: a side's
distance is the expectation of its bins under their softmax, sum_k softmax(l)_k * k, in units of the
stride; the cell's anchor is its centre, ((column + 0.5) * s, (row + 0.5) * s) [input px]; the box is
anchor -/+ the distances. Rows are ordered stride by stride, row-major: the graph's own order.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from avsim.perception.coco.labels import COCO_CLASSES
from avsim.perception.nanodet import fetch
from avsim.perception.nanodet.network import (GRAPH_INPUT_HW, SIZE_MULTIPLE_PX, STRIDES_PX, NanoDetNetwork,
                                              feature_sizes, normalise_bgr)

SIDES = 4
# How `--perception nanodet` runs it: on the camera's region of interest enlarged by 2, as the two other COCO
# networks see the road by default, with class-wise NMS at IoU 0.6, NanoDet's own.
INPUT_UPSCALE = 2.0
NMS_IOU = 0.6


def decode(outputs: tuple[tuple[torch.Tensor, torch.Tensor], ...], input_hw: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
    """The network's (scores, side logits) per stride for an input of `input_hw` -> (boxes (B, N, 4)
    x1, y1, x2, y2 [input px], scores (B, N, 80)), every stride's cells together."""
    boxes, scores = [], []
    for (cls, sides), stride, (rows, cols) in zip(outputs, STRIDES_PX, feature_sizes(*input_hw)):
        batch, cells, channels = sides.shape
        bins = channels // SIDES
        weights = torch.softmax(sides.reshape(batch, cells, SIDES, bins), dim=-1)
        distance = (weights * torch.arange(bins, dtype=weights.dtype)).sum(-1) * stride  # (B, N, 4) [px]
        row, col = torch.meshgrid(torch.arange(rows, dtype=weights.dtype), torch.arange(cols, dtype=weights.dtype),
                                  indexing="ij")
        centre = torch.stack([(col.reshape(-1) + 0.5) * stride, (row.reshape(-1) + 0.5) * stride], dim=-1)  # (N, 2)
        boxes.append(torch.cat([centre - distance[..., :2], centre + distance[..., 2:]], dim=-1))
        scores.append(cls)
    return torch.cat(boxes, dim=1), torch.cat(scores, dim=1)


class NanoDetModel(nn.Module):
    """`detect(images, min_score)` and the sizes `YoloRunner` asks of its model; class_names are COCO's."""

    def __init__(self, network: NanoDetNetwork) -> None:
        super().__init__()
        self.network = network.eval()
        self.class_names = COCO_CLASSES

    @property
    def input_size_px(self) -> tuple[int, int]:
        """(width, height) the graph was exported at."""
        return GRAPH_INPUT_HW[1], GRAPH_INPUT_HW[0]

    @property
    def size_multiple_px(self) -> int:
        """What the input's width and height must be multiples of [px] (the largest stride)."""
        return SIZE_MULTIPLE_PX

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, 3, H, W) float RGB 0-255 -> (boxes (B, N, 4) [input px], class scores (B, N, 80)) before any NMS."""
        return decode(self.network(normalise_bgr(images)), tuple(images.shape[-2:]))

    def detect(self, images: torch.Tensor, min_score: float) -> torch.Tensor:
        """(1, 3, H, W) -> (1, n, 6) float32: x1, y1, x2, y2 [input px], score, class of every (box, class)
        scoring at least `min_score`, highest first; no NMS."""
        boxes, scores = self(images.float().contiguous())
        box_index, class_index = torch.nonzero(scores[0] >= min_score, as_tuple=True)
        rows = torch.cat([boxes[0, box_index], scores[0, box_index, class_index, None],
                          class_index[:, None].to(scores.dtype)], dim=1).float()
        return rows[torch.argsort(rows[:, 4], descending=True, stable=True)][None]


def load_nanodet(json_path: Path | None = None) -> NanoDetModel:
    """The model from the fetched graph (sha256-checked), or from `json_path` with its .bin beside it."""
    return NanoDetModel(NanoDetNetwork(fetch.model_paths()[0] if json_path is None else json_path))
