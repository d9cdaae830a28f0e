"""Darknet's layer types as PyTorch modules, each built from its cfg `Section`.

Semantics follow Darknet's own code (and OpenCV 4's importer of it, the reference of
tests/perception/yolo/test_yolo_reference.py):
- `[convolutional]`: `pad=1` means padding size // 2 (an explicit `padding` wins);
  batch norm is folded into the convolution's weights and bias when the .weights are loaded
  (`weights`), so the module is always a biased conv followed by its activation.
- `[maxpool]`: `padding` defaults to size - 1, of which padding // 2 goes before the row or
  column and the rest after; padded cells never win the max. So the `size=2 stride=1` pool
  of YOLOv3-tiny keeps 13 x 13 at 13 x 13, each output the max of its cell and the cells
  right of and below it.
- `[upsample]`: nearest neighbour by `stride`, times `scale`.
- `[route]`: the listed layers' outputs concatenated on channels (negative numbers count
  back from this layer); with `groups`, only group `group_id` of each input's channels
  (YOLOv4-tiny's CSP blocks).
- `[shortcut]`: this layer's input plus layer `from`'s output, then its activation.
- `[yolo]`: passes its input through; the decoding is `decode`'s job.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from avsim.perception.yolo.cfg import Section

LEAKY_SLOPE = 0.1  # Darknet's leaky ReLU


def activation(name: str, section: Section) -> nn.Module:
    """The module for Darknet activation `name`."""
    modules = {"linear": nn.Identity, "leaky": lambda: nn.LeakyReLU(LEAKY_SLOPE), "relu": nn.ReLU,
               "logistic": nn.Sigmoid, "mish": nn.Mish, "swish": nn.SiLU}
    if name not in modules:
        raise section.fail(f"activation {name!r} is not supported; avsim reads {', '.join(modules)}")
    return modules[name]()


class Convolutional(nn.Module):
    """`[convolutional]`: conv (bias holds the folded batch norm) then activation.

    batch_normalize: whether the .weights store batch-norm statistics for it (read by `weights`).
    """

    def __init__(self, section: Section, in_channels: int) -> None:
        super().__init__()
        size = section.int("size", 1)
        stride = section.int("stride", 1)
        if section.int("stride_x", stride) != stride or section.int("stride_y", stride) != stride:
            raise section.fail("stride_x / stride_y different from stride are not supported")
        padding = section.int("padding", size // 2 if section.int("pad", 0) else 0)
        groups = section.int("groups", 1)
        filters = section.int("filters")
        if filters < 1 or size < 1 or stride < 1 or groups < 1 or in_channels % groups or filters % groups:
            raise section.fail(f"filters={filters}, size={size}, stride={stride}, groups={groups} do not fit "
                               f"{in_channels} input channels")
        self.batch_normalize = bool(section.int("batch_normalize", 0))
        self.conv = nn.Conv2d(in_channels, filters, size, stride, padding, dilation=section.int("dilation", 1),
                              groups=groups, bias=True)
        self.act = activation(section.text("activation", "logistic"), section)
        self.stride = stride

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, c_in, H, W) -> (B, filters, H / stride, W / stride): conv (batch norm folded in), activation."""
        return self.act(self.conv(x))


class MaxPool(nn.Module):
    """`[maxpool]` with Darknet's padding (module docstring)."""

    def __init__(self, section: Section) -> None:
        super().__init__()
        self.size = section.int("size", 2)
        self.stride = section.int("stride", 1)
        if section.int("stride_x", self.stride) != self.stride or section.int("stride_y", self.stride) != self.stride:
            raise section.fail("stride_x / stride_y different from stride are not supported")
        if section.int("maxpool_depth", 0):
            raise section.fail("maxpool_depth is not supported")
        self.padding = section.int("padding", self.size - 1)
        if self.size < 1 or self.stride < 1 or self.padding < 0:
            raise section.fail(f"size={self.size}, stride={self.stride}, padding={self.padding} is not a pooling")

    def _pads(self, length: int) -> tuple[int, int]:
        out = (length + self.padding - self.size) // self.stride + 1
        before = self.padding // 2
        after = max(0, (out - 1) * self.stride + self.size - before - length)
        return before, after

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, C, H, W) -> (B, C, H_out, W_out), H_out = (H + padding - size) // stride + 1 (Darknet pads with -inf)."""
        (top, bottom), (left, right) = self._pads(x.shape[-2]), self._pads(x.shape[-1])
        if top or bottom or left or right:
            x = F.pad(x, (left, right, top, bottom), value=float("-inf"))
        return F.max_pool2d(x, self.size, self.stride)


class Upsample(nn.Module):
    """`[upsample]`: nearest neighbour by `stride`, values times `scale`."""

    def __init__(self, section: Section) -> None:
        super().__init__()
        self.stride = section.int("stride", 2)
        self.scale = section.float("scale", 1.0)
        if self.stride < 1:
            raise section.fail(f"stride={self.stride}: downsampling (negative stride) is not supported")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, C, H, W) -> (B, C, H * stride, W * stride), nearest neighbour, times `scale`."""
        x = F.interpolate(x, scale_factor=self.stride, mode="nearest")
        return x * self.scale if self.scale != 1.0 else x


class Route(nn.Module):
    """`[route]`: sources (absolute layer indices), and which channel group of each to take."""

    def __init__(self, sources: tuple[int, ...], groups: int, group_id: int) -> None:
        super().__init__()
        self.sources = sources
        self.groups = groups
        self.group_id = group_id

    def forward(self, inputs: list[torch.Tensor]) -> torch.Tensor:
        """The sources' chosen channel groups, concatenated along channels (one source: as it is)."""
        if self.groups > 1:
            inputs = [x.chunk(self.groups, dim=1)[self.group_id] for x in inputs]
        return inputs[0] if len(inputs) == 1 else torch.cat(inputs, dim=1)


class Shortcut(nn.Module):
    """`[shortcut]`: previous output + layer `source`'s output, then the activation."""

    def __init__(self, section: Section, source: int) -> None:
        super().__init__()
        if section.text("weights_type", "none") != "none":
            raise section.fail("weighted shortcuts (weights_type) are not supported")
        self.source = source
        self.act = activation(section.text("activation", "linear"), section)

    def forward(self, x: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
        """`x + other` (same shape), then the activation."""
        if x.shape != other.shape:
            raise ValueError(f"shortcut of {tuple(x.shape)} and {tuple(other.shape)}: shapes differ")
        return self.act(x + other)


class Yolo(nn.Module):
    """`[yolo]`: a detection head. Passes its input (B, A * (5 + classes), H, W) through.

    anchors_px: (A, 2) float32 buffer, the masked anchors' (w, h) [network input px];
    scale_x_y: YOLOv4's grid sensitivity (1 in YOLOv3).
    """

    def __init__(self, section: Section, in_channels: int) -> None:
        super().__init__()
        if section.int("new_coords", 0):
            raise section.fail("new_coords=1 (scaled-YOLOv4 box coding) is not supported")
        self.classes = section.int("classes", 20)
        values = section.floats("anchors")
        if len(values) % 2:
            raise section.fail(f"anchors has {len(values)} numbers; it lists (w, h) pairs")
        pairs = [values[i:i + 2] for i in range(0, len(values), 2)]
        mask = section.ints("mask", tuple(range(len(pairs))))
        if any(not 0 <= m < len(pairs) for m in mask):
            raise section.fail(f"mask {list(mask)} names anchors that do not exist (there are {len(pairs)})")
        if in_channels != len(mask) * (5 + self.classes):
            raise section.fail(f"its input has {in_channels} channels, but {len(mask)} anchors x (5 + {self.classes} "
                               f"classes) need {len(mask) * (5 + self.classes)}; fix filters= of the conv before it")
        self.register_buffer("anchors_px", torch.tensor([pairs[m] for m in mask], dtype=torch.float32))
        self.scale_x_y = section.float("scale_x_y", 1.0)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The head's input unchanged; decoding is `avsim.perception.yolo.decode`."""
        return x
