"""The sign detector network: residual backbone, FPN neck, decoupled heads at strides 8 and 16.

Input: (B, 3, H_in, W_in) RGB in [0, 1] (see `letterbox`); H_in, W_in multiples of 32.
Output: one tensor per stride in `STRIDES`, each (B, 1 + num_classes + 4, H_in/s, W_in/s):
  channel 0                  objectness logit
  channels 1 .. num_classes  class logits (sigmoid, one-vs-all), in SIGN_CLASSES order
  last 4 channels            box (dx, dy, log_w, log_h): centre = cell centre + (dx, dy) * s,
                             size = exp(log_w, log_h) * s [input pixels] (`boxes.decode_boxes`)

Stride 8 is assigned signs up to 64 px (an 8 px sign is one cell), stride 16 signs from
32 px up (`assign.SCALE_RANGES_PX`); stride 32 only feeds context into the FPN.

Deployed input size: 640x480 (`DEPLOY_INPUT_SIZE`), the camera's own resolution, so the
letterbox is the identity: no resampling blur, and a 12 px sign keeps its 12 px. The box
height, which the policy turns into a distance, is regressed in camera pixels.
Why this layout: on this 2-core CPU the cost is dominated by per-op overhead and by
the stride 2-8 maps, so the net has few layers (23 convs, 1x1 FPN fusions, no CSP/SPP)
and a ReLU-family activation (SiLU costs ~4x a ReLU per element here).

build_detector() defaults: 0.455 M params (1.8 MB fp32), 1.47 GFLOPs (0.74 GMACs) at 640x480.
Measured on this machine (2-core AMD EPYC VM, torch 2.13 CPU, fused, channels_last,
inference_mode; median of 100 frames after warm-up, nothing else running,
`python -m avsim.bench.detector_latency`): letterbox 0.2 ms + forward 17.3 ms +
decode/NMS 0.8 ms = 18.4 ms per frame at 1 thread, and 11.4 ms at 2 threads. The forward
runs at about 85 GFLOP/s on one core, most of what the core's FMA units can do, so the net
itself has little left to give: the closed loop runs it on a region of interest instead
(`roi`; 480x384 px for the front camera, 11.9 ms at 1 thread in `avsim bench`).
A smaller input, 512x384, would shrink a 12 px sign to 9.6 px; the region keeps the native scale.
"""

from __future__ import annotations

import torch
from torch import nn

from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.layers import Bottleneck, ConvBNAct, fuse_all

STRIDES = (8, 16)
DEPLOY_INPUT_SIZE = (640, 480)  # (W_in, H_in)
BOX_CHANNELS = 4
OBJ_PRIOR = 0.01  # initial objectness probability: keeps the first losses small
INIT_LOG_SIZE = 0.7  # initial log(box size / stride): boxes start about 2 strides wide


class Backbone(nn.Module):
    """(B, 3, H, W) -> C3 (B, w2, H/8, W/8), C4 (B, w3, H/16, W/16), C5 (B, w4, H/32, W/32).

    Stem: two 3x3 stride-2 convs (stride 4); then per stage a 3x3 stride-2 conv and
    `depth` residual bottlenecks.
    """

    def __init__(self, widths: tuple[int, int, int, int, int], depth: int, act: str) -> None:
        super().__init__()
        w0, w1, w2, w3, w4 = widths
        self.stem = nn.Sequential(ConvBNAct(3, w0, 3, 2, act=act), ConvBNAct(w0, w1, 3, 2, act=act))
        self.stage3 = self._stage(w1, w2, depth, act)
        self.stage4 = self._stage(w2, w3, depth, act)
        self.stage5 = self._stage(w3, w4, depth, act)

    @staticmethod
    def _stage(c_in: int, c_out: int, depth: int, act: str) -> nn.Sequential:
        return nn.Sequential(ConvBNAct(c_in, c_out, 3, 2, act=act), *(Bottleneck(c_out, 0.5, act) for _ in range(depth)))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(B, 3, H, W) -> (C3, C4, C5) at strides 8, 16 and 32 (class docstring)."""
        c3 = self.stage3(self.stem(x))
        c4 = self.stage4(c3)
        return c3, c4, self.stage5(c4)


class Neck(nn.Module):
    """FPN top-down path with 1x1 fusions: (C3, C4, C5) -> P3 (B, n3, H/8, W/8), P4 (B, n4, H/16, W/16)."""

    def __init__(self, c3: int, c4: int, c5: int, n3: int, n4: int, act: str) -> None:
        super().__init__()
        self.lateral5 = ConvBNAct(c5, n4, 1, act=act)
        self.fuse4 = ConvBNAct(n4 + c4, n4, 1, act=act)
        self.lateral4 = ConvBNAct(n4, n3, 1, act=act)
        self.fuse3 = ConvBNAct(n3 + c3, n3, 1, act=act)
        self.up = nn.Upsample(scale_factor=2.0, mode="nearest")

    def forward(self, c3: torch.Tensor, c4: torch.Tensor, c5: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(C3, C4, C5) -> (P3, P4): the coarser map upsampled x2 and fused into the finer, twice."""
        p4 = self.fuse4(torch.cat([self.up(self.lateral5(c5)), c4], dim=1))
        p3 = self.fuse3(torch.cat([self.up(self.lateral4(p4)), c3], dim=1))
        return p3, p4


class Head(nn.Module):
    """Decoupled head for one scale: (B, c_in, h, w) -> (B, 1 + num_classes + 4, h, w).

    A classification branch (3x3 conv) gives the class logits; a regression branch
    (3x3 conv) gives the objectness and the box, so objectness follows localisation (YOLOX).
    """

    def __init__(self, c_in: int, width: int, num_classes: int, act: str) -> None:
        super().__init__()
        self.cls_conv = ConvBNAct(c_in, width, 3, act=act)
        self.reg_conv = ConvBNAct(c_in, width, 3, act=act)
        self.cls_pred = nn.Conv2d(width, num_classes, 1)
        self.reg_pred = nn.Conv2d(width, 1 + BOX_CHANNELS, 1)  # objectness, then the box
        prior_logit = float(torch.log(torch.tensor(OBJ_PRIOR / (1.0 - OBJ_PRIOR))))
        nn.init.normal_(self.cls_pred.weight, std=0.01)
        nn.init.constant_(self.cls_pred.bias, 0.0)  # classes are trained on positive cells only
        nn.init.normal_(self.reg_pred.weight, std=0.01)
        with torch.no_grad():
            self.reg_pred.bias.copy_(torch.tensor([prior_logit, 0.0, 0.0, INIT_LOG_SIZE, INIT_LOG_SIZE]))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, c_in, h, w) -> (B, 1 + num_classes + 4, h, w): objectness logit, class logits, box."""
        reg = self.reg_pred(self.reg_conv(x))
        return torch.cat([reg[:, :1], self.cls_pred(self.cls_conv(x)), reg[:, 1:]], dim=1)


class SignDetector(nn.Module):
    """Backbone + neck + one head per stride; see the module docstring for the output layout."""

    strides = STRIDES

    def __init__(self, num_classes: int, widths: tuple[int, int, int, int, int], depth: int,
                 neck_widths: tuple[int, int], head_widths: tuple[int, int], act: str) -> None:
        super().__init__()
        self.num_classes = num_classes
        self.backbone = Backbone(widths, depth, act)
        self.neck = Neck(widths[2], widths[3], widths[4], neck_widths[0], neck_widths[1], act)
        self.heads = nn.ModuleList([Head(neck_widths[0], head_widths[0], num_classes, act),
                                    Head(neck_widths[1], head_widths[1], num_classes, act)])

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """(B, 3, H_in, W_in) in [0, 1] -> [(B, 1 + num_classes + 4, H_in/8, W_in/8),
        (B, 1 + num_classes + 4, H_in/16, W_in/16)]."""
        p3, p4 = self.neck(*self.backbone(x))
        return [self.heads[0](p3), self.heads[1](p4)]

    def fuse(self) -> SignDetector:
        """Fold every BatchNorm into its conv for deployment; puts the model in eval mode, returns self."""
        self.eval()
        return fuse_all(self)


def _round8(x: float) -> int:
    return max(8, int(round(x / 8.0)) * 8)


def build_detector(width_mult: float = 1.0, depth: int = 1, num_classes: int = len(SIGN_CLASSES),
                   act: str = "leaky_relu") -> SignDetector:
    """The detector; channel widths are the base widths below times `width_mult`, rounded to 8.

    width_mult: 1.0 is the deployed size (latency in the module docstring).
    depth: residual bottlenecks per backbone stage (strides 8, 16, 32).
    act: activation, one of `layers.ACTIVATIONS`.
    Base widths: backbone (16, 32, 48, 96, 128) at strides 2..32, neck (48, 64) and
    head branches (48, 64) at strides 8 and 16.
    """
    if width_mult <= 0 or depth < 0 or num_classes < 1:
        raise ValueError(f"need width_mult > 0, depth >= 0, num_classes >= 1; got {width_mult}, {depth}, {num_classes}")
    widths = tuple(_round8(w * width_mult) for w in (16, 32, 48, 96, 128))
    neck = tuple(_round8(w * width_mult) for w in (48, 64))
    heads = tuple(_round8(w * width_mult) for w in (48, 64))
    return SignDetector(num_classes, widths, depth, neck, heads, act)  # type: ignore[arg-type]


def count_macs(model: nn.Module, input_size: tuple[int, int]) -> int:
    """Convolution multiply-accumulates for one (1, 3, H_in, W_in) input; input_size is (W_in, H_in)."""
    total = 0

    def hook(module: nn.Conv2d, _inputs: tuple, output: torch.Tensor) -> None:
        nonlocal total
        k_h, k_w = module.kernel_size
        total += output.numel() * (module.in_channels // module.groups) * k_h * k_w

    handles = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, nn.Conv2d)]
    was_training = model.training
    try:
        with torch.no_grad():
            model.eval()(torch.zeros(1, 3, input_size[1], input_size[0]))
    finally:
        model.train(was_training)
        for handle in handles:
            handle.remove()
    return total
