"""TensorFlow ops of the CenterNet graph as PyTorch modules, with TensorFlow's semantics.

Tensors flow in NCHW (PyTorch's layout); the graph's attributes speak NHWC, so axis
attributes are mapped (`NHWC_TO_NCHW`) and HWIO kernels transposed to OIHW when a module is
built. What needs care, and how each op matches TensorFlow:

- 'SAME' padding (`same_padding`): TensorFlow pads total = max((ceil(n/s) - 1)*s + k - n, 0)
  with the odd pixel at the *end*. A stride-2 3x3 conv on 512 px pads 0 before and 1 after,
  where PyTorch's `padding=1` would pad 1 on both sides and shift every output by a pixel.
  Asymmetric cases run a kernel with one leading zero row / column under symmetric padding
  of the larger side (`_shift_for_padding`): TF's window exactly, with no padded copy.
- `_FusedConv2D` / `FusedDepthwiseConv2dNative`: the conv, then `fused_ops` in order:
  BiasAdd (one extra argument), then Relu, Relu6 or Prelu (its alpha is a second extra
  argument). `epsilon` only matters for a fused FusedBatchNorm, which this graph never has
  (`num_args` = 1 everywhere), so a FusedBatchNorm is refused rather than guessed at.
- `DepthwiseConv2dNative`: kernel [kh, kw, in, multiplier]; output channel i*multiplier + m,
  i.e. a grouped conv with groups = in.
- `ResizeBilinear` with align_corners = half_pixel_centers = False (`resize_bilinear_tf`):
  output pixel i samples the input at i * in/out (no half-pixel shift), lerping towards
  index min(ceil(src), n - 1): the last rows repeat the edge. `F.interpolate` uses half-pixel
  centres and would differ everywhere.
- Elementwise ops broadcast as in NumPy; a per-channel constant (shape [C]) is reshaped to
  [C, 1, 1] for NCHW. `Mean` over NHWC axes (1, 2) is a mean over H, W.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

NHWC_TO_NCHW = {0: 0, 1: 2, 2: 3, 3: 1}


def nchw_axis(axis: int, rank: int = 4) -> int:
    """An NHWC axis (negative allowed) of a rank-4 tensor -> the same axis in NCHW."""
    if rank != 4:
        raise ValueError(f"only rank-4 axes are remapped, got rank {rank}")
    return NHWC_TO_NCHW[axis % 4]


def same_padding(size: int, kernel: int, stride: int, dilation: int = 1) -> tuple[int, int]:
    """TensorFlow 'SAME' padding (before, after) of one spatial dimension."""
    effective = (kernel - 1) * dilation + 1
    out = math.ceil(size / stride)
    total = max((out - 1) * stride + effective - size, 0)
    return total // 2, total - total // 2


_ACTIVATIONS = {"Relu": F.relu, "Relu6": F.relu6, "Sigmoid": torch.sigmoid}
# The fused inference path's input dtypes, and the oneDNN post-op (name, scalars) of each activation.
_ONEDNN_DTYPES = (torch.float32, torch.bfloat16)
_ONEDNN_ACTIVATIONS = {None: ("none", []), "Relu": ("relu", []), "Relu6": ("hardtanh", [0.0, 6.0]),
                       "Sigmoid": ("sigmoid", []), "HardSwish": ("hardswish", [])}


def _shift_for_padding(weight: torch.Tensor, extra_before_hw: tuple[int, int]) -> torch.Tensor:
    """The kernel with `extra_before_hw` leading zero rows / columns.

    TF's SAME pads one pixel more *after* than before when the total is odd. A kernel with
    one leading zero row, under symmetric padding of the larger amount, sees exactly TF's
    window: the zero tap lands on the extra leading pad pixel. So no padded copy of the
    input is made, and the sums are the same (the extra products are exact zeros).
    """
    extra_h, extra_w = extra_before_hw
    return F.pad(weight, (extra_w, 0, extra_h, 0))


class TfConv2d(nn.Module):
    """Conv2D / DepthwiseConv2dNative, optionally fused with BiasAdd and an activation.

    kernel_hwio: the TF kernel, [kh, kw, in, out] (or [kh, kw, in, multiplier] with
    depthwise=True). Input and output (B, C, H, W).
    activation: None, "Relu", "Relu6", "Prelu" (the graph's fused ops), or, when the network
    builder has folded the ops that follow the conv into it, "Sigmoid" or "HardSwish":
    hard_swish_scale * y * relu6(y + 3), the graph's hard swish with its own constant
    (0.16662598, 1/6 in float16, not 1/6).

    Two paths compute the same function. With autograd recording (an attack optimising
    pixels), plain `F.conv2d` and elementwise ops. Without it (`torch.inference_mode()` or
    `no_grad`), one oneDNN convolution with the bias and activation as post-ops, which
    saves a pass over the output per fused op; they agree to float32 rounding. The oneDNN
    path also runs a module cast to bfloat16 on bfloat16 input (`coco.bf16`): products
    of bf16 values summed in float32, the post-ops applied before the result is rounded
    to bf16.
    """

    def __init__(self, kernel_hwio: np.ndarray, strides_hw: tuple[int, int], padding: str, depthwise: bool,
                 dilations_hw: tuple[int, int] = (1, 1), bias: np.ndarray | None = None,
                 activation: str | None = None, prelu_alpha: np.ndarray | None = None,
                 hard_swish_scale: float | None = None) -> None:
        super().__init__()
        kh, kw, cin, cout = kernel_hwio.shape
        if depthwise:
            # [kh, kw, in, mult] -> [in * mult, 1, kh, kw]: output channel i * mult + m.
            weight = np.ascontiguousarray(kernel_hwio.transpose(2, 3, 0, 1)).reshape(cin * cout, 1, kh, kw)
            self.groups = cin
        else:
            weight = np.ascontiguousarray(kernel_hwio.transpose(3, 2, 0, 1))
            self.groups = 1
        self.weight = nn.Parameter(torch.from_numpy(weight.copy()), requires_grad=False)
        self.bias = None if bias is None else nn.Parameter(torch.from_numpy(bias.copy()), requires_grad=False)
        self.kernel_hw = (kh, kw)
        self.strides_hw = strides_hw
        self.dilations_hw = dilations_hw
        if padding not in ("SAME", "VALID"):
            raise ValueError(f"padding {padding!r} is not supported (SAME or VALID)")
        self.padding = padding
        if activation not in (None, "Relu", "Relu6", "Prelu", "Sigmoid", "HardSwish"):
            raise ValueError(f"fused activation {activation!r} is not supported")
        if (activation == "HardSwish") != (hard_swish_scale is not None):
            raise ValueError("a HardSwish activation needs its scale, and only it takes one")
        self.activation = activation
        self.hard_swish_scale = hard_swish_scale
        self.prelu_alpha = None if prelu_alpha is None else nn.Parameter(
            torch.from_numpy(prelu_alpha.reshape(-1, 1, 1).copy()), requires_grad=False)
        self._shifted: dict[tuple[int, int], torch.Tensor] = {}

    def _padding(self, height: int, width: int) -> tuple[tuple[int, int], tuple[int, int]]:
        """(symmetric padding (h, w), leading zero taps (h, w)) reproducing TF's padding."""
        if self.padding == "VALID":
            return (0, 0), (0, 0)
        top, bottom = same_padding(height, self.kernel_hw[0], self.strides_hw[0], self.dilations_hw[0])
        left, right = same_padding(width, self.kernel_hw[1], self.strides_hw[1], self.dilations_hw[1])
        if self.dilations_hw != (1, 1) and (top != bottom or left != right):
            raise ValueError("asymmetric SAME padding with dilation is not supported")
        return (bottom, right), (bottom - top, right - left)

    def _weight_for(self, extra_hw: tuple[int, int]) -> torch.Tensor:
        if extra_hw == (0, 0):
            return self.weight
        cached = self._shifted.get(extra_hw)
        if cached is None or cached.device != self.weight.device or cached.dtype != self.weight.dtype:
            self._shifted[extra_hw] = _shift_for_padding(self.weight.detach(), extra_hw).contiguous(
                memory_format=torch.channels_last)
        return self._shifted[extra_hw]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, C_in, H, W) NCHW -> (B, C_out, H', W') with TF's SAME or VALID padding and the fused
        activation; through oneDNN's fused convolution when no gradient is wanted on the CPU."""
        padding, extra = self._padding(x.shape[-2], x.shape[-1])
        if (torch.is_grad_enabled() or self.activation == "Prelu" or x.dtype not in _ONEDNN_DTYPES
                or x.device.type != "cpu"):
            weight = self.weight if extra == (0, 0) else _shift_for_padding(self.weight, extra)
            y = F.conv2d(x, weight, self.bias, self.strides_hw, padding, self.dilations_hw, self.groups)
            return self._activate(y)
        name, scalars = _ONEDNN_ACTIVATIONS[self.activation]
        y = torch.ops.mkldnn._convolution_pointwise(x, self._weight_for(extra), self.bias, list(padding),
                                                    list(self.strides_hw), list(self.dilations_hw), self.groups,
                                                    name, scalars, None)
        if self.activation == "HardSwish":
            # oneDNN's hard swish is y * relu6(y + 3) / 6; the graph scales by its own constant.
            y.mul_(6.0 * self.hard_swish_scale)
        return y

    def _activate(self, y: torch.Tensor) -> torch.Tensor:
        if self.activation is None:
            return y
        if self.activation == "Prelu":
            return torch.where(y >= 0, y, y * self.prelu_alpha)
        if self.activation == "HardSwish":
            # The graph's order: Mul(scale, y) * Relu6(Add(y, 3)).
            return (self.hard_swish_scale * y) * F.relu6(y + 3.0)
        return _ACTIVATIONS[self.activation](y)


def _channel_constant(value: np.ndarray) -> torch.Tensor:
    """A graph constant as a tensor that broadcasts against NCHW: [C] becomes [C, 1, 1]."""
    tensor = torch.from_numpy(np.asarray(value, dtype=np.float32).copy())
    if tensor.ndim == 1 and tensor.numel() > 1:
        return tensor.reshape(-1, 1, 1)
    if tensor.ndim > 1:
        raise ValueError(f"elementwise constants of shape {tuple(tensor.shape)} are not supported")
    return tensor


class Binary(nn.Module):
    """Mul, Add or Sub of two tensors, or of a tensor and a constant (either side)."""

    _FUNCS = {"Mul": torch.mul, "Add": torch.add, "AddV2": torch.add, "Sub": torch.sub}

    def __init__(self, op: str, constant: np.ndarray | None = None, constant_first: bool = False) -> None:
        super().__init__()
        self.op = op
        self.func = self._FUNCS[op]
        self.constant_first = constant_first
        if constant is None:
            self.constant = None
        else:
            self.register_buffer("constant", _channel_constant(constant))

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        """The op on two tensors (broadcast), or on one and the constant ((C, 1, 1) per channel, or a scalar)."""
        if self.constant is None:
            return self.func(inputs[0], inputs[1])
        if self.constant_first:
            return self.func(self.constant, inputs[0])
        return self.func(inputs[0], self.constant)


class Unary(nn.Module):
    """Relu, Relu6, Sigmoid or Identity."""

    _FUNCS = {"Relu": F.relu, "Relu6": F.relu6, "Sigmoid": torch.sigmoid, "Identity": lambda x: x}

    def __init__(self, op: str) -> None:
        super().__init__()
        self.op = op
        self.func = self._FUNCS[op]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The op applied elementwise; same shape out."""
        return self.func(x)


class Mean(nn.Module):
    """Mean over NHWC axes, mapped to NCHW."""

    def __init__(self, axes_nhwc: list[int], keep_dims: bool) -> None:
        super().__init__()
        self.dims = tuple(sorted(nchw_axis(a) for a in axes_nhwc))
        self.keep_dims = keep_dims

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The mean of NCHW `x` over the mapped axes, kept as size 1 when keep_dims."""
        if x.dtype == torch.bfloat16 and self.dims == (2, 3) and not torch.is_grad_enabled():
            # The same float32 sum, divided and rounded once; torch's bf16 mean first copies
            # the whole tensor to float32, which costs three times as much.
            pooled = F.avg_pool2d(x, tuple(x.shape[-2:]))
            return pooled if self.keep_dims else pooled.flatten(2).squeeze(-1)
        return x.mean(dim=self.dims, keepdim=self.keep_dims)


class Concat(nn.Module):
    """ConcatV2 along an NHWC axis, mapped to NCHW."""

    def __init__(self, axis_nhwc: int) -> None:
        super().__init__()
        self.dim = nchw_axis(axis_nhwc)

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        """The NCHW `inputs` joined along the mapped axis."""
        return torch.cat(inputs, dim=self.dim)


def _source_taps(out_size: int, in_size: int, device: torch.device) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Indices (lower, upper) and lerp weights of TF's legacy bilinear resize along one axis.

    src = i * in/out (computed in float64, as TF.js does in JavaScript numbers); lower =
    floor(src), upper = min(ceil(src), in - 1), weight = src - lower.
    """
    src = torch.arange(out_size, dtype=torch.float64, device=device) * (in_size / out_size)
    lower = torch.floor(src).clamp(min=0)
    upper = torch.ceil(src).clamp(max=in_size - 1)
    return lower.long(), upper.long(), (src - lower).float()


def resize_bilinear_tf(x: torch.Tensor, out_hw: tuple[int, int]) -> torch.Tensor:
    """TF's ResizeBilinear with align_corners = half_pixel_centers = False, on (B, C, H, W).

    Differentiable in x. Computed as TF.js's CPU kernel does: lerp along x on the two source
    rows, then along y: top + (bottom - top) * row_weight.
    """
    out_h, out_w = out_hw
    in_h, in_w = x.shape[-2:]
    if (out_h, out_w) == (in_h, in_w):
        return x
    y0, y1, wy = _source_taps(out_h, in_h, x.device)
    x0, x1, wx = _source_taps(out_w, in_w, x.device)
    # Gather whole rows, then columns, in NHWC: contiguous copies when x is channels-last.
    pixels = x.permute(0, 2, 3, 1)
    rows_top, rows_bottom = pixels.index_select(1, y0), pixels.index_select(1, y1)
    wx = wx.reshape(-1, 1)
    top = rows_top.index_select(2, x0)
    top = top + (rows_top.index_select(2, x1) - top) * wx
    bottom = rows_bottom.index_select(2, x0)
    bottom = bottom + (rows_bottom.index_select(2, x1) - bottom) * wx
    return (top + (bottom - top) * wy.reshape(-1, 1, 1)).permute(0, 3, 1, 2)


def upscale_bilinear_tf(x: torch.Tensor, factor: int) -> torch.Tensor:
    """`resize_bilinear_tf` of (B, C, H, W) to (factor * H, factor * W), bit for bit, for a
    power-of-two factor; differentiable in x. Channels-last memory out.

    Output column factor * i + r samples the input at i + r / factor: the same lerp as TF's,
    p[i] + (p[min(i + 1, W - 1)] - p[i]) * (r / factor), with the weight exact in binary, done
    for every column of a residue r at once instead of by gathering; then the same along y.
    The sums are TF's own, in its order, so for finite inputs the result equals
    `resize_bilinear_tf`'s exactly (`tests/perception/coco/test_coco_ops.py`).
    """
    if factor < 1 or factor & (factor - 1):
        raise ValueError(f"upscale_bilinear_tf takes a power-of-two factor, got {factor}")
    if factor == 1:
        return x
    pixels = x.permute(0, 2, 3, 1)  # (B, H, W, C)
    for axis in (2, 1):  # along x first, as TF lerps the two source rows, then between them
        following = torch.cat([pixels.narrow(axis, 1, pixels.shape[axis] - 1), pixels.narrow(axis, -1, 1)], dim=axis)
        step = following - pixels
        # r = 0 is the source pixel itself: TF's p + (p - p) * 0, exactly p.
        shifted = [pixels] + [pixels + step * (r / factor) for r in range(1, factor)]
        shape = list(pixels.shape)
        shape[axis] *= factor
        pixels = torch.stack(shifted, dim=axis + 1).reshape(shape)
    return pixels.permute(0, 3, 1, 2)


class ResizeBilinear(nn.Module):
    """The graph's ResizeBilinear with a fixed integer scale factor per axis.

    The graph stores the output size as a constant for its 512 px input; the factor (2 in
    every resize of this graph, Keras' UpSampling2D) lets the same module run on other input
    sizes.
    """

    def __init__(self, scale_hw: tuple[int, int], align_corners: bool, half_pixel_centers: bool) -> None:
        super().__init__()
        if align_corners or half_pixel_centers:
            raise ValueError("only ResizeBilinear with align_corners = half_pixel_centers = False is supported")
        self.scale_hw = scale_hw

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, C, H, W) -> (B, C, s_h H, s_w W), sampled as TF's legacy bilinear resize."""
        return upsample_bilinear_tf(x, self.scale_hw)


def upsample_bilinear_tf(x: torch.Tensor, scale_hw: tuple[int, int]) -> torch.Tensor:
    """`resize_bilinear_tf` to (s_h * H, s_w * W) for integer factors, in one native kernel.

    TF samples output j at j / s, and the last s - 1 outputs lean on a repeated edge. The
    same samples come from PyTorch's align_corners=True resize of the input with its edge
    row and column repeated once, (H + 1, W + 1) -> (s_h * H + 1, s_w * W + 1), which maps
    j to j * H / (s_h * H) = j / s_h exactly, then dropping the last output row and column.
    The weights are the same (multiples of 1 / s); the sums agree to float32 rounding.
    """
    height, width = x.shape[-2:]
    padded = F.pad(x, (0, 1, 0, 1), mode="replicate")
    out = F.interpolate(padded, size=(scale_hw[0] * height + 1, scale_hw[1] * width + 1), mode="bilinear",
                        align_corners=True)
    out = out[..., : scale_hw[0] * height, : scale_hw[1] * width]
    # Keep the input's memory layout: the slice is a strided view, and a conv fed from it
    # (through the head's concat) would otherwise run in the slower NCHW layout.
    layout = torch.channels_last if x.is_contiguous(memory_format=torch.channels_last) else torch.contiguous_format
    return out.contiguous(memory_format=layout)
