"""A Darknet network built from its cfg: pixels -> the raw output of each `[yolo]` head.

`DarknetNetwork(sections)` builds one module per layer section (`layers`) and runs them in
file order, keeping each output where a later `[route]` or `[shortcut]` reads it. Input:
(B, C, H, W) float, RGB in 0..1 as Darknet feeds it, H and W multiples of
`size_multiple_px` (32 for the YOLO tinies) so that upsampled maps line up with the ones
they are concatenated with. Fully differentiable.
"""

from __future__ import annotations

import torch
from torch import nn

from avsim.perception.yolo.cfg import Section
from avsim.perception.yolo.layers import Convolutional, MaxPool, Route, Shortcut, Upsample, Yolo

LAYER_KINDS = ("convolutional", "maxpool", "upsample", "route", "shortcut", "yolo")


def _absolute(section: Section, index: int, ref: int, count: int) -> int:
    """Layer reference `ref` (negative: counted back from layer `index`) as an absolute index."""
    target = index + ref if ref < 0 else ref
    if not 0 <= target < index:
        raise section.fail(f"refers to layer {ref}, which is not an earlier layer (this is layer {index} of {count})")
    return target


class DarknetNetwork(nn.Module):
    """The layers of a Darknet cfg as one module.

    Attributes: input_size_px (width, height) and input_channels from [net];
    heads: the `Yolo` modules in file order; size_multiple_px: the largest downsampling of
    any layer, which input sizes must be multiples of.
    """

    def __init__(self, sections: list[Section]) -> None:
        super().__init__()
        net, layer_sections = sections[0], sections[1:]
        self.input_size_px = (net.int("width", 416), net.int("height", 416))
        self.input_channels = net.int("channels", 3)
        self.layers = nn.ModuleList()
        channels: list[int] = []
        strides: list[int] = []
        count = len(layer_sections)
        for index, section in enumerate(layer_sections):
            c_in = channels[-1] if channels else self.input_channels
            stride_in = strides[-1] if strides else 1
            if section.kind == "convolutional":
                layer = Convolutional(section, c_in)
                c_out, stride_out = layer.conv.out_channels, stride_in * layer.stride
            elif section.kind == "maxpool":
                layer = MaxPool(section)
                c_out, stride_out = c_in, stride_in * layer.stride
            elif section.kind == "upsample":
                layer = Upsample(section)
                c_out, stride_out = c_in, max(1, stride_in // layer.stride)
            elif section.kind == "route":
                sources = tuple(_absolute(section, index, ref, count) for ref in section.ints("layers"))
                groups, group_id = section.int("groups", 1), section.int("group_id", 0)
                if not sources or groups < 1 or not 0 <= group_id < groups or any(channels[s] % groups for s in sources):
                    raise section.fail(f"layers={list(sources)}, groups={groups}, group_id={group_id} is not a route")
                layer = Route(sources, groups, group_id)
                c_out, stride_out = sum(channels[s] // groups for s in sources), strides[sources[0]]
            elif section.kind == "shortcut":
                refs = section.ints("from")
                if len(refs) != 1:
                    raise section.fail(f"from={list(refs)}: avsim reads shortcuts from exactly one layer")
                layer = Shortcut(section, _absolute(section, index, refs[0], count))
                c_out, stride_out = c_in, stride_in
            elif section.kind == "yolo":
                layer = Yolo(section, c_in)
                c_out, stride_out = c_in, stride_in
            else:
                raise section.fail(f"layer type [{section.kind}] is not supported; avsim reads "
                                   f"{', '.join(f'[{k}]' for k in LAYER_KINDS)} (YOLOv3/v4-tiny style cfgs)")
            self.layers.append(layer)
            channels.append(c_out)
            strides.append(stride_out)
        self.heads = [layer for layer in self.layers if isinstance(layer, Yolo)]
        if not self.heads:
            raise net.fail("the cfg has no [yolo] layer, so the network detects nothing")
        self.size_multiple_px = max(strides)
        # Which outputs must be kept for a later route or shortcut.
        self._kept = {s for layer in self.layers if isinstance(layer, Route) for s in layer.sources}
        self._kept |= {layer.source for layer in self.layers if isinstance(layer, Shortcut)}

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """(B, C, H, W) input -> per `[yolo]` head, its raw (B, A * (5 + classes), H_s, W_s) map."""
        kept: dict[int, torch.Tensor] = {}
        heads = []
        for index, layer in enumerate(self.layers):
            if isinstance(layer, Route):
                x = layer([kept[s] for s in layer.sources])
            elif isinstance(layer, Shortcut):
                x = layer(x, kept[layer.source])
            else:
                x = layer(x)
            if isinstance(layer, Yolo):
                heads.append(x)
            if index in self._kept:
                kept[index] = x
        return heads
