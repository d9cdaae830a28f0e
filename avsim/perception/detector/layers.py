"""Building blocks: Conv-BN-activation and a residual bottleneck, with BN folding.

Every block keeps its spatial size unless it has a stride; shapes below are
(B, C, H, W). `fuse_conv_bn` folds a BatchNorm into the preceding convolution for
deployment: y = gamma * (conv(x) - mean) / sqrt(var + eps) + beta becomes one conv
with weight W * gamma / sqrt(var + eps) and bias beta + (b - mean) * gamma / sqrt(var + eps).
"""

from __future__ import annotations

import torch
from torch import nn


ACTIVATIONS = ("relu", "leaky_relu", "hardswish", "silu")


def make_activation(name: str) -> nn.Module:
    """In-place activation by name; ReLU-like ones cost ~1/4 of SiLU on this CPU."""
    if name == "relu":
        return nn.ReLU(inplace=True)
    if name == "leaky_relu":
        return nn.LeakyReLU(0.1, inplace=True)
    if name == "hardswish":
        return nn.Hardswish(inplace=True)
    if name == "silu":
        return nn.SiLU(inplace=True)
    raise ValueError(f"unknown activation '{name}', expected one of {ACTIVATIONS}")


def fuse_conv_bn(conv: nn.Conv2d, bn: nn.BatchNorm2d) -> nn.Conv2d:
    """A new conv (with bias) equal to `bn(conv(x))` in eval mode."""
    fused = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride, conv.padding,
                      conv.dilation, conv.groups, bias=True, padding_mode=conv.padding_mode)
    with torch.no_grad():
        inv_std = torch.rsqrt(bn.running_var + bn.eps)
        scale = bn.weight * inv_std
        fused.weight.copy_(conv.weight * scale.reshape(-1, 1, 1, 1))
        conv_bias = conv.bias if conv.bias is not None else torch.zeros_like(bn.running_mean)
        fused.bias.copy_(bn.bias + (conv_bias - bn.running_mean) * scale)
    return fused.to(conv.weight.device)


class ConvBNAct(nn.Module):
    """Conv2d (no bias) -> BatchNorm -> activation; (B, c_in, H, W) -> (B, c_out, H/stride, W/stride).

    `padding` defaults to kernel // 2 ("same" for odd kernels); a kernel-4 stride-4
    patchify stem uses padding 0.
    """

    def __init__(self, c_in: int, c_out: int, kernel: int = 3, stride: int = 1, groups: int = 1,
                 act: str | None = "relu", padding: int | None = None) -> None:
        super().__init__()
        self.conv = nn.Conv2d(c_in, c_out, kernel, stride, kernel // 2 if padding is None else padding,
                              groups=groups, bias=False)
        self.bn: nn.Module = nn.BatchNorm2d(c_out, eps=1e-3, momentum=0.03)
        self.act: nn.Module = make_activation(act) if act else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, c_in, H, W) -> (B, c_out, H / stride, W / stride): conv, batch norm, activation."""
        return self.act(self.bn(self.conv(x)))

    def fuse(self) -> None:
        """Fold the BatchNorm into the conv (eval-mode statistics); idempotent."""
        if isinstance(self.bn, nn.BatchNorm2d):
            self.conv = fuse_conv_bn(self.conv, self.bn)
            self.bn = nn.Identity()


class Bottleneck(nn.Module):
    """1x1 (c -> c*expansion) then 3x3 (-> c), plus the input: (B, c, H, W) -> same."""

    def __init__(self, c: int, expansion: float = 0.5, act: str = "relu") -> None:
        super().__init__()
        hidden = max(8, int(c * expansion))
        self.cv1 = ConvBNAct(c, hidden, 1, act=act)
        self.cv2 = ConvBNAct(hidden, c, 3, act=act)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, c, H, W) -> (B, c, H, W): x plus the two-conv residual branch."""
        return x + self.cv2(self.cv1(x))


def fuse_all(module: nn.Module) -> nn.Module:
    """Fold every ConvBNAct's BatchNorm in `module` (in place); returns `module`."""
    for child in module.modules():
        if isinstance(child, ConvBNAct):
            child.fuse()
    return module
