"""Probe: YOLOv3-tiny's network alone, fp32 against bf16, at the loop's default input, one thread.

The deployed front input is the camera's region of interest (352x256 px with the study's camera)
enlarged x2 (`perception.yolo_upscale`): 704x512, channels-last. Both precisions run in one process,
alternating in rounds, on the same random images, so that other work on the machine slows both
alike; the median of each is printed, with its CPU time. Only the network: no pre-processing,
decoding or NMS (the `avsim bench` yolo rows time those too).

    MUJOCO_GL=egl python experiments/probes/yolo_network_time.py --rounds 5
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from avsim.perception.yolo.bf16 import Bf16Yolo
from avsim.perception.yolo.model import PIXEL_SCALE, load_yolo

INPUT_HW_PX = (512, 704)  # the front region, 256x352 px, upscaled x2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5, help="rounds of 5 frames per precision")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model = load_yolo()
    networks = {"fp32": (model.network, torch.float32), "bf16": (Bf16Yolo(model).network, torch.bfloat16)}
    images = torch.rand(1, 3, *INPUT_HW_PX, generator=torch.Generator().manual_seed(0)) * 255 * PIXEL_SCALE
    wall_ms: dict[str, list[float]] = {name: [] for name in networks}
    cpu_ms: dict[str, list[float]] = {name: [] for name in networks}
    with torch.inference_mode():
        for name, (network, dtype) in networks.items():  # warm-up: oneDNN builds its kernels on first use
            network(images.to(dtype).contiguous(memory_format=torch.channels_last))
        for _ in range(args.rounds):
            for name, (network, dtype) in networks.items():
                x = images.to(dtype).contiguous(memory_format=torch.channels_last)
                for _ in range(5):
                    wall0, cpu0 = time.perf_counter(), time.process_time()
                    network(x)
                    wall_ms[name].append(1e3 * (time.perf_counter() - wall0))
                    cpu_ms[name].append(1e3 * (time.process_time() - cpu0))
    for name in networks:
        print(f"YOLOv3-tiny network, {name}, {INPUT_HW_PX[1]}x{INPUT_HW_PX[0]}, 1 thread: "
              f"{statistics.median(wall_ms[name]):.1f} ms wall, {statistics.median(cpu_ms[name]):.1f} ms CPU (median of "
              f"{len(wall_ms[name])})")


if __name__ == "__main__":
    main()
