"""The CenterNet network as PyTorch modules, built node by node from the TF.js graph.

`CenterNet.from_graph` walks the graph from its input placeholder to the two dense outputs,
`tower_0/keypoints` (the class heatmap, after the sigmoid) and `tower_0/wh` (the box
regression), and turns every node on the way into a module of `ops` whose weights are the
graph's dequantised constants. The graph's decoding tail (MaxPool, Equal, TopKV2, GatherV2
and their index arithmetic) lives in `decode`, which reproduces it for any input size.

Two elementwise tails that follow a conv are folded into it (`_foldable_activations`): the
hard swish MobileNetV3 exports as four nodes, and a sigmoid; the conv then computes them in
the graph's own order (see `ops.TfConv2d`), or as oneDNN post-ops when nothing needs gradients.

Input: (B, 3, H, W) float RGB, values 0-255 as the graph takes them (it has no separate
normalisation step: its first conv works on raw values), H and W
multiples of 32 (the head upsamples stride-32 features twice by 2 and concatenates them with
stride-16 and stride-8 ones). The graph was exported for 512 x 512.
Outputs, both (B, ., H/4, W/4), NCHW:
  heatmap  [B, 80, H/4, W/4]  per-class centre probability (COCO-80 order, 0-based)
  wh       [B, 4, H/4, W/4]   distances from the cell's anchor (4*col, 4*row) to the box's
                              left, top, right and bottom edges [input px]
Everything from input pixels to these maps is differentiable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import nn

from avsim.perception.coco.graph import GraphNode, TfjsGraph, read_graph
from avsim.perception.coco.ops import Binary, Concat, Mean, ResizeBilinear, TfConv2d, Unary

INPUT_NAME = "tower_0/images"
HEATMAP_NAME = "tower_0/keypoints"
WH_NAME = "tower_0/wh"
OUTPUT_STRIDE = 4
SIZE_MULTIPLE_PX = 32

_CONV_OPS = {"Conv2D", "_FusedConv2D", "DepthwiseConv2dNative", "FusedDepthwiseConv2dNative"}
_BINARY_OPS = {"Mul", "Add", "AddV2", "Sub"}
_UNARY_OPS = {"Relu", "Relu6", "Sigmoid", "Identity"}


class UnsupportedGraphError(ValueError):
    """The graph uses an op or an attribute this port does not implement."""


@dataclass(frozen=True)
class _Step:
    """Run module `index` on the named values; store the result as `output`; then free `release`."""

    index: int
    inputs: tuple[str, ...]
    output: str
    release: tuple[str, ...]


def _ancestors(graph: TfjsGraph, outputs: tuple[str, ...]) -> list[GraphNode]:
    """The non-constant nodes the outputs depend on, in an order where inputs come first."""
    by_name = {node.name: node for node in graph.nodes}
    order: list[GraphNode] = []
    state: dict[str, int] = {}  # 1: on the stack, 2: done

    def visit(name: str) -> None:
        if name in graph.constants or state.get(name) == 2:
            return
        if state.get(name) == 1:
            raise UnsupportedGraphError(f"the graph has a cycle through {name}")
        state[name] = 1
        node = by_name[name]
        for producer, _ in node.inputs:
            visit(producer)
        state[name] = 2
        order.append(node)

    for name in outputs:
        visit(name)
    return order


def _fused_activation(node: GraphNode) -> tuple[bool, str | None]:
    """(has bias, activation) of a fused conv's fused_ops; refuses what the port cannot do."""
    fused = list(node.attrs.get("fused_ops", []))
    if not fused:
        return False, None
    if fused[0] != "BiasAdd":
        raise UnsupportedGraphError(f"{node.name}: fused ops {fused} (only BiasAdd, then Relu/Relu6/Prelu, are supported)")
    if len(fused) == 1:
        return True, None
    if len(fused) == 2 and fused[1] in ("Relu", "Relu6", "Prelu"):
        return True, fused[1]
    raise UnsupportedGraphError(f"{node.name}: fused ops {fused} (only BiasAdd, then Relu/Relu6/Prelu, are supported)")


def _hw(values: list[int], default: int = 1) -> tuple[int, int]:
    """NHWC [1, h, w, 1] strides or dilations -> (h, w)."""
    return (int(values[1]), int(values[2])) if values else (default, default)


def dense_node_names(graph: TfjsGraph) -> set[str]:
    """Names of the nodes from the input to the heatmap and wh outputs (what `CenterNet` runs)."""
    return {node.name for node in _ancestors(graph, (HEATMAP_NAME, WH_NAME))}


class CenterNet(nn.Module):
    """The dense part of the graph (input pixels -> heatmap, wh); see the module docstring."""

    def __init__(self, modules: list[nn.Module], steps: list[_Step], node_names: list[str]) -> None:
        super().__init__()
        self.nodes = nn.ModuleList(modules)
        self.node_names = node_names
        self._steps = steps

    @classmethod
    def from_graph(cls, graph: TfjsGraph) -> "CenterNet":
        """The network that computes the graph's heatmap and wh outputs from its input placeholder, each
        graph node a module (activations folded into their convolutions); unsupported graphs raise
        `UnsupportedGraphError`.
        """
        order = _ancestors(graph, (HEATMAP_NAME, WH_NAME))
        if not order or order[0].name != INPUT_NAME:
            raise UnsupportedGraphError(f"the outputs do not start at the input placeholder {INPUT_NAME}")
        spatial = _spatial_sizes(graph, order)
        folded = _foldable_activations(graph, order)
        absorbed = {name for _, _, nodes in folded.values() for name in nodes}
        modules, steps, names = [], [], []
        for node in order[1:]:
            if node.name in absorbed:
                continue
            dynamic = tuple(name for name, _ in node.inputs if name not in graph.constants)
            # A conv with a folded tail produces the tail's last value, under that name.
            activation, scale, produced = folded.get(node.name, (None, None, (node.name,)))
            output = produced[-1]
            modules.append(_build_module(node, graph, spatial, activation, scale))
            steps.append(_Step(len(modules) - 1, dynamic, output, ()))
            names.append(output)
        return cls(modules, _with_releases(steps, (HEATMAP_NAME, WH_NAME)), names)

    @classmethod
    def from_files(cls, json_path: Path) -> "CenterNet":
        """The network of the TF.js model.json at `json_path` (weights beside it), in eval mode."""
        return cls.from_graph(read_graph(json_path)).eval()

    def producer_index(self, name: str) -> int:
        """Index in `nodes` of the module that computes the named value, looking through
        Identity nodes (e.g. HEATMAP_NAME: the heatmap's conv, with its sigmoid folded in)."""
        for step in self._steps:
            if step.output == name:
                module = self.nodes[step.index]
                if isinstance(module, Unary) and module.op == "Identity":
                    return self.producer_index(step.inputs[0])
                return step.index
        raise KeyError(f"no module of the network produces {name!r}")

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """images (B, 3, H, W) RGB 0-255 -> (heatmap (B, 80, H/4, W/4), wh (B, 4, H/4, W/4))."""
        height, width = images.shape[-2:]
        if height % SIZE_MULTIPLE_PX or width % SIZE_MULTIPLE_PX:
            raise ValueError(f"CenterNet input must be a multiple of {SIZE_MULTIPLE_PX} px a side, got {width}x{height}")
        values = {INPUT_NAME: images}
        for step in self._steps:
            values[step.output] = self.nodes[step.index](*(values[name] for name in step.inputs))
            for name in step.release:
                del values[name]
        return values[HEATMAP_NAME], values[WH_NAME]


def _with_releases(steps: list[_Step], keep: tuple[str, ...]) -> list[_Step]:
    """Free each intermediate value right after its last use (peak memory, and cache reuse)."""
    last_use: dict[str, int] = {}
    for i, step in enumerate(steps):
        for name in step.inputs:
            last_use[name] = i
    out = []
    for i, step in enumerate(steps):
        release = tuple(sorted({name for name in step.inputs if last_use[name] == i and name not in keep}))
        out.append(_Step(step.index, step.inputs, step.output, release))
    return out


def _spatial_sizes(graph: TfjsGraph, order: list[GraphNode]) -> dict[str, tuple[int, int]]:
    """(H, W) of every 4-D value at the graph's own input size: the resize factors come from it."""
    shape = graph.input_shapes.get(INPUT_NAME)
    if not shape or len(shape) != 4 or min(shape[1:3]) <= 0:
        raise UnsupportedGraphError(f"the input {INPUT_NAME} has no fixed NHWC shape ({shape})")
    sizes = {INPUT_NAME: (shape[1], shape[2])}
    for node in order[1:]:
        dynamic = [name for name, _ in node.inputs if name not in graph.constants]
        if node.op in _CONV_OPS:
            h, w = sizes[dynamic[0]]
            kernel = graph.constants[node.inputs[1][0]].shape
            sh, sw = _hw(node.attrs.get("strides", []))
            if node.attrs.get("padding") == "VALID":
                sizes[node.name] = ((h - kernel[0]) // sh + 1, (w - kernel[1]) // sw + 1)
            else:  # SAME: ceil(n / stride), as `ops.same_padding` pads for
                sizes[node.name] = (math.ceil(h / sh), math.ceil(w / sw))
        elif node.op == "Mean":
            h, w = sizes[dynamic[0]]
            axes = [int(a) % 4 for a in graph.constants[node.inputs[1][0]].reshape(-1)]
            sizes[node.name] = (1 if 1 in axes else h, 1 if 2 in axes else w)
        elif node.op == "ResizeBilinear":
            size = graph.constants[node.inputs[1][0]].reshape(-1)
            sizes[node.name] = (int(size[0]), int(size[1]))
        else:
            # Elementwise and concat: the largest of the inputs (a Mean's 1x1 broadcasts).
            candidates = [sizes[name] for name in dynamic if name in sizes]
            sizes[node.name] = max(candidates, key=lambda hw: hw[0] * hw[1])
    return sizes


def _consumers(order: list[GraphNode]) -> dict[str, list[GraphNode]]:
    consumers: dict[str, list[GraphNode]] = {}
    for node in order:
        for name, _ in node.inputs:
            consumers.setdefault(name, []).append(node)
    return consumers


def _scalar(graph: TfjsGraph, name: str) -> float | None:
    value = graph.constants.get(name)
    return float(value.reshape(-1)[0]) if value is not None and value.size == 1 else None


def _foldable_activations(graph: TfjsGraph, order: list[GraphNode]) -> dict[str, tuple[str, float | None, tuple[str, ...]]]:
    """Elementwise tails that can run inside the conv before them: conv name ->
    (activation, hard-swish scale, the absorbed nodes, last one being the new output).

    Two patterns, each only where the conv's output feeds nothing else:
    - hard swish, as MobileNetV3 exports it: m = Mul(s, y), a = Add(y, 3), r = Relu6(a),
      out = Mul(m, r); i.e. s * y * relu6(y + 3) with the graph's s;
    - Sigmoid(y).
    """
    consumers = _consumers(order)
    folded = {}
    for node in order:
        if node.op not in _CONV_OPS or _fused_activation(node)[1] is not None:
            continue
        users = consumers.get(node.name, [])
        if len(users) == 1 and users[0].op == "Sigmoid":
            folded[node.name] = ("Sigmoid", None, (users[0].name,))
            continue
        if len(users) != 2 or {u.op for u in users} != {"Mul", "Add"}:
            continue
        mul = next(u for u in users if u.op == "Mul")
        add = next(u for u in users if u.op == "Add")
        scale = next((_scalar(graph, n) for n, _ in mul.inputs if n != node.name), None)
        three = next((_scalar(graph, n) for n, _ in add.inputs if n != node.name), None)
        relu6 = consumers.get(add.name, [])
        if scale is None or three != 3.0 or len(relu6) != 1 or relu6[0].op != "Relu6":
            continue
        tail = consumers.get(relu6[0].name, [])
        if (len(tail) != 1 or tail[0].op != "Mul" or consumers.get(mul.name, []) != tail
                or {n for n, _ in tail[0].inputs} != {mul.name, relu6[0].name}):
            continue
        folded[node.name] = ("HardSwish", scale, (mul.name, add.name, relu6[0].name, tail[0].name))
    return folded


def _build_module(node: GraphNode, graph: TfjsGraph, spatial: dict[str, tuple[int, int]],
                  folded_activation: str | None = None, hard_swish_scale: float | None = None) -> nn.Module:
    constants = graph.constants
    inputs = node.inputs
    attrs = node.attrs
    if node.op in _CONV_OPS:
        if attrs.get("data_format", "NHWC") != "NHWC":
            raise UnsupportedGraphError(f"{node.name}: data_format {attrs.get('data_format')} (only NHWC)")
        if attrs.get("padding") not in ("SAME", "VALID"):
            raise UnsupportedGraphError(f"{node.name}: padding {attrs.get('padding')} (only SAME and VALID)")
        has_bias, activation = _fused_activation(node) if node.op.startswith(("_Fused", "Fused")) else (False, None)
        extra = [constants[name] for name, _ in inputs[2:]]
        if len(extra) != has_bias + (activation == "Prelu"):
            raise UnsupportedGraphError(f"{node.name}: {len(extra)} extra arguments for fused ops {attrs.get('fused_ops')}")
        return TfConv2d(constants[inputs[1][0]], _hw(attrs.get("strides", [])), attrs["padding"],
                        depthwise="Depthwise" in node.op, dilations_hw=_hw(attrs.get("dilations", [])),
                        bias=extra[0] if has_bias else None, activation=folded_activation or activation,
                        prelu_alpha=extra[1] if activation == "Prelu" else None, hard_swish_scale=hard_swish_scale)
    if node.op in _BINARY_OPS:
        first, second = (name for name, _ in inputs)
        if first in constants:
            return Binary(node.op, constants[first], constant_first=True)
        if second in constants:
            return Binary(node.op, constants[second])
        return Binary(node.op)
    if node.op in _UNARY_OPS:
        return Unary(node.op)
    if node.op == "Mean":
        return Mean([int(a) for a in constants[inputs[1][0]].reshape(-1)], bool(attrs.get("keep_dims", False)))
    if node.op == "ConcatV2":
        return Concat(int(constants[inputs[-1][0]].reshape(-1)[0]))
    if node.op == "ResizeBilinear":
        (in_h, in_w), (out_h, out_w) = spatial[inputs[0][0]], spatial[node.name]
        if out_h % in_h or out_w % in_w:
            raise UnsupportedGraphError(f"{node.name}: resize {in_h}x{in_w} -> {out_h}x{out_w} is not by an integer factor")
        return ResizeBilinear((out_h // in_h, out_w // in_w), bool(attrs.get("align_corners", False)),
                              bool(attrs.get("half_pixel_centers", False)))
    raise UnsupportedGraphError(f"{node.name}: op {node.op} is not supported by the PyTorch port")
