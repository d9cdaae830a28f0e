"""The graph's decoding tail, `tower_0/detections`, for heatmaps of any size.

In the TF.js graph, after the dense outputs (`network`):

    peaks  = keypoints * Cast(Equal(keypoints, MaxPool3x3 SAME(keypoints)))   local maxima
    score, index = TopKV2(Reshape(peaks, [1, -1]), k=100, sorted)            over (row, col, class)
    class = index mod C;  cell = index div C;  row = cell div W;  col = cell mod W
    l, t, r, b = GatherV2(Reshape(wh, [H*W, 4]), row * W + col)
    detections = ConcatV2([4*col - l, 4*row - t, 4*col + r, 4*row + b, score, class])

`decode_detections` does the same in PyTorch. Two details matter for equality:
- MaxPool 'SAME' ignores the padding (it pads with -inf), as `F.max_pool2d(padding=1)` does;
- TF.js's CPU TopK breaks ties by the lower flat index; `torch.topk` promises no order among
  ties, so the candidates at or above the k-th value are re-sorted stably.
The constants (k, the stride 4, the class count) are read from the graph (`DecodeSpec`).
Scores are differentiable in the heatmap; the indices are not (they are a selection).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from avsim.perception.coco.graph import TfjsGraph
from avsim.perception.coco.network import UnsupportedGraphError

# The graph's names for the decoding constants.
_TOP_K = "tower_0/TopKV2/k"
_STRIDE_MULS = ("tower_0/mul_3/y", "tower_0/mul_4/y", "tower_0/mul_5/y", "tower_0/mul_6/y")
_CLASSES = "tower_0/strided_slice_7"
# The ops of the decoding tail, all implemented by `decode_detections`.
TAIL_OPS = frozenset({"MaxPool", "Equal", "Cast", "Mul", "Add", "Sub", "Reshape", "TopKV2", "ExpandDims", "FloorDiv",
                      "FloorMod", "GatherV2", "StridedSlice", "ConcatV2", "Identity"})


@dataclass(frozen=True)
class DecodeSpec:
    """k: detections kept; stride_px: input pixels per heatmap cell; num_classes: heatmap channels."""

    k: int = 100
    stride_px: float = 4.0
    num_classes: int = 80

    @classmethod
    def from_graph(cls, graph: TfjsGraph, dense_nodes: set[str]) -> "DecodeSpec":
        """The decoding constants, after checking that the tail holds only ops implemented here."""
        tail_ops = {node.op for node in graph.nodes if node.name not in dense_nodes and node.op != "Placeholder"}
        if not tail_ops <= TAIL_OPS:
            raise UnsupportedGraphError(f"the decoding tail uses ops {sorted(tail_ops - TAIL_OPS)}, not implemented")
        try:
            strides = {float(graph.constants[name].reshape(-1)[0]) for name in _STRIDE_MULS}
            k = int(graph.constants[_TOP_K].reshape(-1)[0])
            classes = int(graph.constants[_CLASSES].reshape(-1)[0])
        except KeyError as exc:
            raise UnsupportedGraphError(f"the decoding tail has no constant {exc}") from None
        if len(strides) != 1:
            raise UnsupportedGraphError(f"the box decoding uses different strides {sorted(strides)}")
        return cls(k=k, stride_px=strides.pop(), num_classes=classes)


def topk_lowest_index_first(values: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Top k of each row of (B, N) `values`, largest first, ties by the lower index (as TF.js)."""
    kth = torch.topk(values, k, dim=1).values[:, -1:]
    top_values, top_indices = [], []
    for row, threshold in zip(values, kth):
        candidates = torch.nonzero(row >= threshold).squeeze(1)  # ascending indices
        order = torch.sort(row[candidates], descending=True, stable=True).indices[:k]
        top_indices.append(candidates[order])
        top_values.append(row[candidates[order]])
    return torch.stack(top_values), torch.stack(top_indices)


def peak_scores(heatmap: torch.Tensor) -> torch.Tensor:
    """(B, C, H, W) heatmap -> the same with every cell that is not a 3x3 local maximum zeroed."""
    pooled = F.max_pool2d(heatmap, kernel_size=3, stride=1, padding=1)
    return heatmap * (heatmap == pooled).to(heatmap.dtype)


def _peaks_at_or_above(heatmap: torch.Tensor, min_value: float) -> tuple[torch.Tensor, torch.Tensor]:
    """(values, flat NHWC indices), in index order, of the 3x3 peaks of a (1, C, H, W) map
    whose value is at least `min_value`: `peak_scores` evaluated only where it can pass.

    Each candidate is compared with its 3x3 neighbourhood, as in the max pool: the test is
    the graph's, cell for cell. Outside the map counts as -inf there; here a neighbour
    outside is clamped back onto the edge row or column, which is inside the same window,
    so the maximum is the same. Candidates are found per cell first (the largest class
    value of a cell), so only the few cells that can pass are searched by class.
    """
    _, num_classes, height, width = heatmap.shape
    by_cell = heatmap[0].permute(1, 2, 0).reshape(height * width, num_classes)  # a view for channels-last maps
    cells = torch.nonzero(by_cell.amax(dim=1) >= min_value).squeeze(1)
    hits = torch.nonzero(by_cell[cells] >= min_value)  # (n, 2): row in `cells`, class; in index order
    cell, cls = cells[hits[:, 0]], hits[:, 1]
    values = by_cell[cell, cls]
    rows, cols = torch.div(cell, width, rounding_mode="floor"), cell % width
    neighbourhood = torch.stack([by_cell[(rows + dy).clamp(0, height - 1) * width + (cols + dx).clamp(0, width - 1), cls]
                                 for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    is_peak = values == neighbourhood.max(dim=0).values
    return values[is_peak], (cell * num_classes + cls)[is_peak]


def decode_detections(heatmap: torch.Tensor, wh: torch.Tensor, spec: DecodeSpec = DecodeSpec(),
                      min_score: float | None = None) -> torch.Tensor:
    """heatmap (B, C, H, W), wh (B, 4, H, W) -> (B, k, 6): x1, y1, x2, y2 [input px], score, class.

    The class is 0-based in COCO-80 order (11 = stop sign). Rows are score-sorted.
    min_score: if given (batch 1 only), return only the rows scoring at least this, found
    without a max pool and top-k over the whole map: exactly the graph's rows, filtered. For
    inference, where the low peaks are dropped anyway; the default path is the graph's.
    """
    batch, num_classes, _, _ = heatmap.shape
    if num_classes != spec.num_classes:
        raise ValueError(f"heatmap has {num_classes} classes, the graph decodes {spec.num_classes}")
    if min_score is not None:
        if batch != 1:
            raise ValueError(f"decoding with min_score takes one image, got {batch}")
        values, index = _peaks_at_or_above(heatmap, min_score)
        # Stable: ties keep the lower index first, as TF.js's top-k does.
        order = torch.sort(values, descending=True, stable=True).indices[:spec.k]
        scores, index = values[order].unsqueeze(0), index[order].unsqueeze(0)
    else:
        # (row, col, class) order, as the graph's NHWC reshape flattens it.
        flat = peak_scores(heatmap).permute(0, 2, 3, 1).reshape(batch, -1)
        scores, index = topk_lowest_index_first(flat, min(spec.k, flat.shape[1]))
    return _rows(scores, index, wh, spec)


# Candidates are taken this far below the threshold's logit, far above float32's rounding of
# the sigmoid, so no cell whose score passes is missed; the score itself then decides.
_LOGIT_MARGIN = 1e-3


def decode_logit_detections(logits: torch.Tensor, wh: torch.Tensor, spec: DecodeSpec, min_score: float) -> torch.Tensor:
    """`decode_detections` with min_score, from the heatmap's logits (before the sigmoid).

    logits (1, C, H, W) and wh (1, 4, H, W), any float dtype -> (1, n, 6) float32. The peaks
    are those of the logits: the sigmoid is increasing, so they are the heatmap's, without
    a sigmoid over the whole map. Each peak's score is sigmoid(logit) in float32. For the
    bfloat16 network (`coco.bf16`); the float32 path keeps the graph's own order of ops.
    """
    batch, num_classes, _, _ = logits.shape
    if num_classes != spec.num_classes or batch != 1:
        raise ValueError(f"logit decoding takes one image of {spec.num_classes} classes, got {tuple(logits.shape)}")
    if not 0 < min_score < 1:
        raise ValueError(f"min_score must be in (0, 1), got {min_score}")
    # float32 holds every bf16 value exactly, and its reductions are the fast ones.
    values, index = _peaks_at_or_above(logits.float(), math.log(min_score / (1 - min_score)) - _LOGIT_MARGIN)
    scores = torch.sigmoid(values)
    passed = scores >= min_score
    scores, index = scores[passed], index[passed]
    order = torch.sort(scores, descending=True, stable=True).indices[:spec.k]
    return _rows(scores[order].unsqueeze(0), index[order].unsqueeze(0), wh.float(), spec)


def _rows(scores: torch.Tensor, index: torch.Tensor, wh: torch.Tensor, spec: DecodeSpec) -> torch.Tensor:
    """(B, k) scores and flat NHWC heatmap indices, wh (B, 4, H, W) -> (B, k, 6) detection rows."""
    batch, _, height, width = wh.shape
    classes = index % spec.num_classes
    cell = torch.div(index, spec.num_classes, rounding_mode="floor")
    rows = torch.div(cell, width, rounding_mode="floor")
    cols = cell % width
    edges = wh.permute(0, 2, 3, 1).reshape(batch, height * width, 4)
    ltrb = torch.gather(edges, 1, cell.unsqueeze(-1).expand(-1, -1, 4))
    anchor_x = cols.to(wh.dtype) * spec.stride_px
    anchor_y = rows.to(wh.dtype) * spec.stride_px
    boxes = torch.stack([anchor_x - ltrb[..., 0], anchor_y - ltrb[..., 1], anchor_x + ltrb[..., 2], anchor_y + ltrb[..., 3]], -1)
    return torch.cat([boxes, scores.unsqueeze(-1), classes.to(wh.dtype).unsqueeze(-1)], dim=-1)
