"""Per-frame detector latency on this CPU, split into letterbox / forward / decode+NMS.

    python -m avsim.bench.detector_latency [--weights PATH] [--runs 50] [--threads 2]

The fused model in channels-last memory under `torch.inference_mode()`, one 640x480 RGB
frame at a time; prints medians (and 90th percentiles) over `--runs` frames after 10
warm-up frames. Without --weights the network has random initial weights: then almost
no cell passes the confidence threshold, so decode+NMS is at its cheapest.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np
import torch

from avsim.boundary import run_guarded
from avsim.perception.detector.infer import DEFAULT_CONF_THRESHOLD
from avsim.perception.detector.letterbox import letterbox
from avsim.validation import OneLineArgumentParser, number_flag
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE, build_detector, count_macs
from avsim.perception.detector.postprocess import decode
from avsim.perception.detector.weights import load_weights

WARMUP_FRAMES = 10


def _frame(rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """A 640x480-like test frame: noisy sky/grass/road bands with a red disc."""
    image = np.empty((height, width, 3), np.uint8)
    image[: height // 2] = (170, 200, 235)
    image[height // 2:] = (80, 120, 60)
    image[int(height * 0.6):, width // 4: 3 * width // 4] = (70, 70, 72)
    noise = rng.normal(0, 4, image.shape)
    image = np.clip(image + noise, 0, 255).astype(np.uint8)
    yy, xx = np.mgrid[:height, :width]
    image[(xx - width * 0.64) ** 2 + (yy - height * 0.45) ** 2 < 9 ** 2] = (180, 20, 30)
    return image


def benchmark(model: torch.nn.Module, input_size: tuple[int, int], runs: int, conf_threshold: float,
              image_size: tuple[int, int] = (640, 480), seed: int = 0) -> dict[str, np.ndarray]:
    """Per-frame times [ms] of each stage over `runs` frames: {"letterbox", "forward", "decode_nms", "total"}."""
    model = model.eval().fuse().to(memory_format=torch.channels_last)
    rng = np.random.default_rng(seed)
    frames = [_frame(rng, *image_size) for _ in range(4)]
    times: dict[str, list[float]] = {"letterbox": [], "forward": [], "decode_nms": [], "total": []}
    with torch.inference_mode():
        for i in range(WARMUP_FRAMES + runs):
            t0 = time.perf_counter()
            tensor, _ = letterbox(frames[i % len(frames)], input_size)
            t1 = time.perf_counter()
            outputs = model(tensor.unsqueeze(0))
            t2 = time.perf_counter()
            decode(outputs, conf_threshold)
            t3 = time.perf_counter()
            if i >= WARMUP_FRAMES:
                for key, value in (("letterbox", t1 - t0), ("forward", t2 - t1), ("decode_nms", t3 - t2), ("total", t3 - t0)):
                    times[key].append(1e3 * value)
    return {key: np.asarray(values) for key, values in times.items()}


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m avsim.bench.detector_latency`: print the detector's per-frame latency; returns the exit status."""
    prog = "python -m avsim.bench.detector_latency"
    parser = OneLineArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    parser.add_argument("--weights", help="trained weights (default: randomly initialised build_detector())")
    parser.add_argument("--runs", type=number_flag(1, 100_000, integer=True), default=50)
    parser.add_argument("--threads", type=number_flag(1, 64, integer=True), default=2)
    parser.add_argument("--conf", type=number_flag(0, 1, lo_open=True, hi_open=True), default=DEFAULT_CONF_THRESHOLD)
    args = parser.parse_args(argv)
    return run_guarded(lambda: _bench(args), prog=prog)


def _bench(args: argparse.Namespace) -> int:
    torch.set_num_threads(args.threads)
    if args.weights:
        model, meta = load_weights(args.weights)
        input_size = (int(meta["input_size"][0]), int(meta["input_size"][1]))
    else:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(0)
            model = build_detector()
        input_size = DEPLOY_INPUT_SIZE
    params = sum(p.numel() for p in model.parameters())
    macs = count_macs(model, input_size)
    times = benchmark(model, input_size, args.runs, args.conf)
    print(f"sign detector, input {input_size[0]}x{input_size[1]}, {params / 1e6:.3f} M params, {2 * macs / 1e9:.2f} GFLOPs, "
          f"{torch.get_num_threads()} threads, fused, channels_last; median (p90) of {args.runs} frames:")
    for key, values in times.items():
        print(f"  {key:<11} {np.median(values):6.2f} ms  ({np.percentile(values, 90):6.2f} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
