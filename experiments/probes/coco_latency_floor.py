"""One-off probe: how fast could the COCO CenterNet possibly run on this CPU, at one thread?

Issue 13 asks for at most 15 ms per frame at one thread, as deployed. The port runs the default input
(the front region upscaled x2, 704x512) in about 48 ms in bf16 (`avsim bench`). This probe asks what
any implementation of this network, on this core, would need at each `perception.coco_input` size:

- the multiply-accumulates of its convolutions, by kind (1x1, depthwise, other), counted on the
  network's own layer shapes (the asymmetric-padding kernels included, as the port runs them);
- every convolution timed alone, on its own input shape, with nothing else in the way: in bf16
  as deployed (oneDNN's fused convolution, weights and activations bf16), and in int8 on oneDNN's
  VNNI kernels (`onednn::qconv2d_pointwise` on pre-packed weights). The int8 weights and inputs are
  random: this times int8 convolutions of these shapes; it says nothing about int8's accuracy;
- the network's per-call cost: the whole bf16 network on a 32x32 input, where the pixels cost
  nothing and what is left is dispatch, oneDNN's per-call set-up and the elementwise ops' calls;
- the whole bf16 network at the input size, as deployed, and what it spends beyond its convolutions.

The sum of the convolutions timed alone is a floor for the network in that arithmetic: the network
runs the same convolutions, each with its own per-call set-up as here, plus its elementwise ops and
resizes. It is not part of
avsim and needs nothing beyond it. Run it on a quiet machine; it takes about ten seconds:

    MUJOCO_GL=egl python experiments/probes/coco_latency_floor.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import torch

from avsim.perception.coco import ops
from avsim.perception.coco.bf16 import Bf16CenterNet
from avsim.perception.coco.model import load_centernet

# perception.coco_input -> the network's input (H, W) [px] for the front camera's region
# (front_roi_px 352x256 px): the whole frame squeezed to 512x512, the region as it is, the region x2.
INPUT_SIZES_HW = {"resize": (512, 512), "crop": (256, 352), "upscale": (512, 704)}
TARGET_MS = 15.0


def median_s(call: Callable[[], object], repeats: int = 15, warmup: int = 3) -> float:
    """Median wall time of `call()` [s] after `warmup` untimed calls."""
    for _ in range(warmup):
        call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def conv_layers(network: torch.nn.Module, height_px: int, width_px: int) -> list[tuple[ops.TfConv2d, torch.Size, torch.Size]]:
    """(conv module, input shape, output shape) of every convolution the network runs at this size."""
    seen = []
    hooks = [m.register_forward_hook(lambda m, i, o: seen.append((m, i[0].shape, o.shape)))
             for m in network.nodes if isinstance(m, ops.TfConv2d)]
    with torch.inference_mode():
        network(torch.zeros(1, 3, height_px, width_px).contiguous(memory_format=torch.channels_last))
    for hook in hooks:
        hook.remove()
    return seen


def time_conv_alone(conv: ops.TfConv2d, in_shape: torch.Size) -> tuple[float, float, int, str]:
    """(bf16 seconds, int8 seconds, multiply-accumulates, kind) of one convolution on its own."""
    padding, extra = conv._padding(in_shape[-2], in_shape[-1])
    weight = conv._weight_for(extra)
    stride, dilation = list(conv.strides_hw), list(conv.dilations_hw)
    generator = torch.Generator().manual_seed(0)
    with torch.inference_mode():
        x_bf16 = (torch.rand(in_shape, generator=generator) * 4).to(torch.bfloat16).contiguous(memory_format=torch.channels_last)
        w_bf16 = weight.to(torch.bfloat16).contiguous(memory_format=torch.channels_last)
        b_bf16 = None if conv.bias is None else conv.bias.to(torch.bfloat16)
        out = torch.ops.mkldnn._convolution_pointwise(x_bf16, w_bf16, b_bf16, list(padding), stride, dilation,
                                                      conv.groups, "none", [], None)
        bf16_s = median_s(lambda: torch.ops.mkldnn._convolution_pointwise(
            x_bf16, w_bf16, b_bf16, list(padding), stride, dilation, conv.groups, "none", [], None))

        x_u8 = torch.randint(0, 256, in_shape, dtype=torch.uint8, generator=generator).contiguous(memory_format=torch.channels_last)
        w_i8 = torch.randint(-127, 128, weight.shape, dtype=torch.int8, generator=generator)
        w_scales = torch.full((weight.shape[0],), 0.01)
        w_zero_points = torch.zeros(weight.shape[0], dtype=torch.int64)
        packed = torch.ops.onednn.qconv_prepack(w_i8, w_scales, 0.1, 0, stride, list(padding), dilation, conv.groups,
                                                list(in_shape))
        bias = None if conv.bias is None else conv.bias.float()
        int8_s = median_s(lambda: torch.ops.onednn.qconv2d_pointwise(
            x_u8, 0.1, 0, packed, w_scales, w_zero_points, bias, stride, list(padding), dilation, conv.groups,
            0.1, 0, None, "none", [], None))
    macs = out.shape[1] * out.shape[2] * out.shape[3] * weight.shape[1] * weight.shape[2] * weight.shape[3]
    kind = "depthwise" if conv.groups > 1 else ("1x1" if weight.shape[-2:] == (1, 1) else "other")
    return bf16_s, int8_s, macs, kind


def main() -> None:
    torch.set_num_threads(1)
    model = load_centernet()
    bf16 = Bf16CenterNet(model)

    def network_s(height_px: int, width_px: int) -> float:
        x = (torch.rand(1, 3, height_px, width_px, generator=torch.Generator().manual_seed(0)) * 255).contiguous(
            memory_format=torch.channels_last)
        with torch.inference_mode():
            return median_s(lambda: bf16(x), repeats=20, warmup=5)

    per_call_ms = 1e3 * network_s(32, 32)
    print(f"COCO CenterNet, 1 thread. Per-call cost (the bf16 network on 32x32 px): {per_call_ms:.1f} ms")
    for mode, (height_px, width_px) in INPUT_SIZES_HW.items():
        by_kind: dict[str, list[float]] = {}
        for conv, in_shape, _ in conv_layers(model.network, height_px, width_px):
            bf16_s, int8_s, macs, kind = time_conv_alone(conv, in_shape)
            totals = by_kind.setdefault(kind, [0.0, 0.0, 0.0, 0])
            totals[0] += macs
            totals[1] += bf16_s
            totals[2] += int8_s
            totals[3] += 1
        whole_ms = 1e3 * network_s(height_px, width_px)
        gmac = sum(t[0] for t in by_kind.values()) / 1e9
        conv_bf16_ms = 1e3 * sum(t[1] for t in by_kind.values())
        conv_int8_ms = 1e3 * sum(t[2] for t in by_kind.values())
        print(f"\n{mode} ({width_px}x{height_px} px): {gmac:.3f} GMAC; the bf16 network as deployed {whole_ms:.1f} ms")
        print(f"  {'convolutions':12s} {'count':>5s} {'GMAC':>6s}   {'bf16 alone':>10s} {'GMAC/s':>7s}   {'int8 alone':>10s} {'GMAC/s':>7s}")
        for kind, (macs, bf16_s, int8_s, count) in sorted(by_kind.items()):
            print(f"  {kind:12s} {count:5d} {macs / 1e9:6.3f}   {1e3 * bf16_s:7.1f} ms {macs / bf16_s / 1e9:7.1f}"
                  f"   {1e3 * int8_s:7.1f} ms {macs / int8_s / 1e9:7.1f}")
        print(f"  {'all':12s} {sum(t[3] for t in by_kind.values()):5d} {gmac:6.3f}   {conv_bf16_ms:7.1f} ms {'':7s}"
              f"   {conv_int8_ms:7.1f} ms")
        print(f"  the network beyond its convolutions (as deployed, less the bf16 convolutions alone): "
              f"{whole_ms - conv_bf16_ms:.1f} ms")
        for name, floor_ms in (("bf16", conv_bf16_ms), ("int8", conv_int8_ms)):
            verdict = "over" if floor_ms > TARGET_MS else "under"
            print(f"  floor in {name}: the convolutions alone, {floor_ms:.1f} ms, {verdict} the {TARGET_MS:.0f} ms target")


if __name__ == "__main__":
    main()
