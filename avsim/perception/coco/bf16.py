"""The COCO CenterNet in bfloat16 for inference: `perception.coco_precision = "bf16"`.

A copy of the float32 network with its weights and activations in bfloat16. oneDNN runs the
convolutions with the CPU's bf16 dot products (AVX-512 BF16 here), summing in float32 and
rounding each layer's output to bf16; the 1x1 convolutions, most of the network's
multiply-adds, run about twice as fast as in float32, and the depthwise ones, bound by
memory traffic, gain from moving half the bytes. It is not the graph's arithmetic: scores
and boxes differ from the float32 port by bf16 rounding (8 significant bits). The float32
network stays as it is: the reference check against TF.js tests it, and attacks
differentiate it (`CocoCenterNet.maps`).

Two layers keep float32 weights and arithmetic (`FLOAT32_LAYERS`): the first bottleneck's
depthwise conv and its projection, 16 channels each at half the input resolution. Rounding
*their weights* to bf16 shifted every stop-sign score down, by 0.024 on average over the
sign's heatmap cells (12 front-camera renders), where rounding the weights of any other
layer moved it by less than 0.003, and rounding any layer's activations by less than 0.001:
a few hundred weights, each off by up to 2^-9 of itself in the same way at every pixel, do
not average out. Their inputs and outputs are still bf16.

Two more savings, neither changing a result of this path:
- the heatmap's conv ends without its sigmoid, and the peaks are found on the logits
  (`decode.decode_logit_detections`): the sigmoid is increasing, so the peaks are the same,
  and only the few peaks that can pass the threshold get a sigmoid, in float32;
- wh is decoded in float32.
"""

from __future__ import annotations

import copy

import torch
from torch import nn

from avsim.perception.coco.decode import decode_detections, decode_logit_detections
from avsim.perception.coco.model import CocoCenterNet
from avsim.perception.coco.network import HEATMAP_NAME
from avsim.perception.coco.ops import TfConv2d
from avsim.perception.cpu_bf16 import require_bf16

FLOAT32_LAYERS = ("tower_0/MobilenetV3/expanded_conv/depthwise/depthwise",
                  "tower_0/MobilenetV3/expanded_conv/project/BatchNorm/FusedBatchNorm")


class Float32Island(nn.Module):
    """Runs a float32 module inside the bf16 network: bf16 in, float32 arithmetic, bf16 out."""

    def __init__(self, module: nn.Module) -> None:
        super().__init__()
        self.module = module

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        """Run the wrapped module in float32 on the bfloat16 inputs; the output back in bfloat16."""
        return self.module(*(x.float() for x in inputs)).to(torch.bfloat16)


class Bf16CenterNet(nn.Module):
    """`detect(images, min_score)` as `CocoCenterNet.detect`, computed in bfloat16.

    images (1, 3, H, W) float RGB 0-255 (cast to bf16 here) -> (1, n, 6) float32 rows:
    x1, y1, x2, y2 [input px], score, class. Inference only: no gradients flow through it.
    """

    def __init__(self, model: CocoCenterNet) -> None:
        super().__init__()
        require_bf16("perception.coco_precision")
        network = copy.deepcopy(model.network)
        heatmap_conv = network.nodes[network.producer_index(HEATMAP_NAME)]
        if not isinstance(heatmap_conv, TfConv2d) or heatmap_conv.activation != "Sigmoid":
            raise ValueError("the heatmap does not come from a conv with its sigmoid folded in; cannot decode logits")
        heatmap_conv.activation = None  # the network now ends in the heatmap's logits
        network.to(torch.bfloat16)
        for name in FLOAT32_LAYERS:
            index = network.producer_index(name)
            network.nodes[index] = Float32Island(copy.deepcopy(model.network.nodes[index]))
        self.network = network.eval()
        self.spec = model.spec

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """images (B, 3, H, W) -> (heatmap logits (B, 80, H/4, W/4), wh (B, 4, H/4, W/4)), bf16."""
        return self.network(images.to(torch.bfloat16))

    def detect(self, images: torch.Tensor, min_score: float | None = None) -> torch.Tensor:
        """(1, 3, H, W) -> (1, n, 6) float32 detections; min_score as in `CocoCenterNet.detect`
        (None: the graph's 100 peaks, from a float32 sigmoid of the whole heatmap)."""
        logits, wh = self(images)
        if min_score is None:
            return decode_detections(torch.sigmoid(logits.float()), wh.float(), self.spec)
        return decode_logit_detections(logits, wh, self.spec, min_score)
