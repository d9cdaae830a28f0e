"""One-off probe: would onnxruntime, in float32 or int8, bring the COCO CenterNet under 15 ms?

Issue 13 asks for at most 15 ms per frame at one thread. avsim's PyTorch port runs the default
input (the front region upscaled x2, 704x512) in 47.6 ms in bf16 (`avsim bench`). This probe
times the same float32 network under onnxruntime, as exported and after static int8
quantisation (per-channel weights, QOperator kernels, which use the CPU's VNNI dot products),
at the `upscale` and `crop` input sizes, one thread, median of 25 runs after 5 warm-ups.

It measures time only. The int8 network is calibrated on one random input, so its scores mean
nothing; its heatmap's largest difference from float32 is printed to show it runs the same
graph. It is not part of avsim and needs one package avsim does not depend on:

    pip install onnxscript            # torch's ONNX exporter
    MUJOCO_GL=egl python experiments/probes/coco_latency_onnxruntime.py

Two workarounds, both for the export alone: `TfConv2d` runs a fused oneDNN op outside autograd,
which ONNX cannot express, so the port is traced with its autograd path; and the kernels it
shifts for TensorFlow's asymmetric SAME padding are cached tensors, which the exporter leaves
dangling, so they are recomputed in the trace and folded into initialisers afterwards.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch
from onnx import numpy_helper
from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static

from avsim.perception.coco import ops
from avsim.perception.coco.model import load_centernet

INPUT_SIZES_HW = {"upscale": (512, 704), "crop": (256, 352)}


def _traceable_weight(conv: ops.TfConv2d, extra_hw: tuple[int, int]) -> torch.Tensor:
    return conv.weight if extra_hw == (0, 0) else ops._shift_for_padding(conv.weight, extra_hw)


def export(path: Path, height_px: int, width_px: int) -> np.ndarray:
    """Write the float32 network for one input size; return the input it was traced with."""
    ops.TfConv2d._weight_for = _traceable_weight
    network = load_centernet().network.to(memory_format=torch.contiguous_format)
    images = torch.rand(1, 3, height_px, width_px, generator=torch.Generator().manual_seed(0)) * 255
    with torch.enable_grad():
        torch.onnx.export(network, (images,), str(path), opset_version=18, dynamo=True,
                          input_names=["images"], output_names=["heatmap", "wh"])
    return images.numpy()


def fold_weight_pads(path: Path) -> None:
    """Replace every Pad of an initialiser by its padded initialiser, in dependency order."""
    model = onnx.load(str(path))
    initialisers = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    kept = []
    for node in model.graph.node:
        if node.op_type == "Pad" and node.input[0] in initialisers:
            weight, pads = initialisers[node.input[0]], initialisers[node.input[1]]
            rank = weight.ndim
            padded = np.pad(weight, [(int(pads[i]), int(pads[i + rank])) for i in range(rank)])
            model.graph.initializer.append(numpy_helper.from_array(padded, node.output[0]))
        else:
            kept.append(node)
    del model.graph.node[:]
    model.graph.node.extend(kept)
    onnx.save(model, str(path))


class OneInput(CalibrationDataReader):
    def __init__(self, images: np.ndarray) -> None:
        self.pending = [{"images": images}]

    def get_next(self):
        return self.pending.pop() if self.pending else None


def median_ms(path: Path, images: np.ndarray) -> tuple[float, np.ndarray]:
    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    heatmap = session.run(None, {"images": images})[0]
    times = []
    for _ in range(30):
        started = time.perf_counter()
        session.run(None, {"images": images})
        times.append(time.perf_counter() - started)
    return 1000 * statistics.median(times[5:]), heatmap


def main() -> int:
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        for mode, (height_px, width_px) in INPUT_SIZES_HW.items():
            fp32, int8 = Path(tmp, f"{mode}.onnx"), Path(tmp, f"{mode}_int8.onnx")
            images = export(fp32, height_px, width_px)
            fold_weight_pads(fp32)
            quantize_static(str(fp32), str(int8), OneInput(images), quant_format=QuantFormat.QOperator,
                            per_channel=True, activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8)
            fp32_ms, fp32_heatmap = median_ms(fp32, images)
            int8_ms, int8_heatmap = median_ms(int8, images)
            print(f"{mode} {width_px}x{height_px}: onnxruntime fp32 {fp32_ms:.1f} ms, int8 {int8_ms:.1f} ms "
                  f"(heatmap max |int8 - fp32| {np.abs(int8_heatmap - fp32_heatmap).max():.3f})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
