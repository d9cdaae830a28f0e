"""The `[yolo]` heads' raw maps -> boxes, objectness and class probabilities, as Darknet decodes them.

For the cell in column i, row j of a head with an S_x x S_y grid over a W x H input, and its
anchor a of size (a_w, a_h) [input px], the raw values (t_x, t_y, t_w, t_h, t_o, t_c...) give

  centre x = (i + (sigmoid(t_x) - 0.5) * scale_x_y + 0.5) * W / S_x     [input px]  (same for y)
  width    = exp(t_w) * a_w                                              [input px]  (same for h)
  objectness = sigmoid(t_o);  class probability = sigmoid(t_c)  (independent logistic classes)

and a class's score is objectness x class probability. Rows are ordered head by head, then
row j, column i, anchor a: the order of OpenCV's Darknet importer, whose output the
reference test compares row for row. Everything here is differentiable.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from avsim.perception.yolo.layers import Yolo


class DecodedBoxes(NamedTuple):
    """boxes_xyxy: (B, N, 4) x1, y1, x2, y2 [input px]; objectness: (B, N); class_prob: (B, N, C)."""

    boxes_xyxy: torch.Tensor
    objectness: torch.Tensor
    class_prob: torch.Tensor

    def class_scores(self) -> torch.Tensor:
        """(B, N, C) objectness x class probability: what Darknet thresholds."""
        return self.objectness.unsqueeze(-1) * self.class_prob


def decode_head(raw: torch.Tensor, head: Yolo, input_hw: tuple[int, int]) -> DecodedBoxes:
    """One head's raw map (B, A * (5 + C), S_y, S_x) -> its S_y * S_x * A rows."""
    batch, _, rows, cols = raw.shape
    anchors = head.anchors_px.to(raw.dtype)
    count = anchors.shape[0]
    t = raw.view(batch, count, 5 + head.classes, rows, cols).permute(0, 3, 4, 1, 2)  # (B, S_y, S_x, A, 5 + C)
    grid_y, grid_x = torch.meshgrid(torch.arange(rows, dtype=raw.dtype), torch.arange(cols, dtype=raw.dtype),
                                    indexing="ij")
    offset_xy = (torch.sigmoid(t[..., 0:2]) - 0.5) * head.scale_x_y + 0.5
    stride_xy = torch.tensor([input_hw[1] / cols, input_hw[0] / rows], dtype=raw.dtype)
    centre_xy = (torch.stack([grid_x, grid_y], dim=-1)[:, :, None, :] + offset_xy) * stride_xy
    size_wh = torch.exp(t[..., 2:4]) * anchors
    boxes = torch.cat([centre_xy - size_wh / 2, centre_xy + size_wh / 2], dim=-1)
    return DecodedBoxes(boxes.reshape(batch, -1, 4), torch.sigmoid(t[..., 4]).reshape(batch, -1),
                        torch.sigmoid(t[..., 5:]).reshape(batch, -1, head.classes))


def decode_heads(raws: list[torch.Tensor], heads: list[Yolo], input_hw: tuple[int, int]) -> DecodedBoxes:
    """Every head's rows, concatenated in head order."""
    parts = [decode_head(raw, head, input_hw) for raw, head in zip(raws, heads, strict=True)]
    return DecodedBoxes(*(torch.cat(items, dim=1) for items in zip(*parts)))


def score_rows(decoded: DecodedBoxes, min_score: float) -> torch.Tensor:
    """(n, 6) float32 rows x1, y1, x2, y2 [input px], score, class for the first image's (box, class)
    pairs scoring at least `min_score`, highest score first. One box may appear under several classes."""
    scores = decoded.class_scores()[0]
    box_index, class_index = torch.nonzero(scores >= min_score, as_tuple=True)
    rows = torch.cat([decoded.boxes_xyxy[0, box_index], scores[box_index, class_index, None],
                      class_index[:, None].to(scores.dtype)], dim=1).float()
    return rows[torch.argsort(rows[:, 4], descending=True, stable=True)]
