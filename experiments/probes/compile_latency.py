"""One-off probe: would torch.compile (TorchInductor) make the two networks of the closed loop faster?

Issue 25 asks for the detector closed loop at 5x real time and the COCO closed loop at 1.5x per core; the
networks are 44 % (own detector, bf16) and 85 % (COCO CenterNet, bf16) of a step (docs/performance.md).
torch.compile fuses a network's elementwise ops into generated C++ loops and can fold its weights
(`torch._inductor.config.freezing`), which eager mode cannot. This probe measures, at one thread, for each
network on its deployed input in its default arithmetic ("auto": bf16 where the CPU has bf16 kernels, fp32 on
others; a Town07 front frame 30 m before the sign, the input made from its front region as each runner makes it):

- the CPU time of one forward pass, eager and compiled (medians of 15 after 3 warm-up calls);
- the time of the first compiled call (the compile), with Inductor's caches empty, as a fresh worker pays it;
- whether the compiled maps are the eager ones bit for bit, and the largest difference if not.

It is not part of avsim; it writes nothing but Inductor's cache, under a temporary folder it removes.
It needs a C++ compiler (Inductor generates and builds C++). Run it on a quiet machine (about a minute):

    MUJOCO_GL=egl python experiments/probes/compile_latency.py
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time

import torch

from avsim.config import SimConfig
from avsim.loop import ClosedLoop
from avsim.perception.coco.bf16 import Bf16CenterNet
from avsim.perception.coco.model import load_centernet
from avsim.perception.coco.preprocess import image_tensor, network_input
from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.perception.detector.letterbox import to_tensor
from avsim.perception.detector.roi import crop_for
from avsim.perception.detector.weights import SHIPPED_WEIGHTS
from avsim.sensors.regions import regions_px
from avsim.vehicle.physics import FRONT_BUMPER_X_M


def median_cpu_ms(call, repeats: int = 15, warmup: int = 3) -> float:
    for _ in range(warmup):
        call()
    times = []
    for _ in range(repeats):
        start = time.process_time()
        call()
        times.append(time.process_time() - start)
    return 1000 * statistics.median(times)


def maps_of(output) -> list[torch.Tensor]:
    return [t.float() for t in (output if isinstance(output, (tuple, list)) else [output])]


def compare(networks: dict) -> None:
    """networks: name -> (forward, example input). Every eager time is taken before anything is compiled, and
    again after, since a compiled graph's worker pool and caches stay in the process."""
    with torch.inference_mode():
        eager = {name: (maps_of(forward(x)), median_cpu_ms(lambda: forward(x))) for name, (forward, x) in networks.items()}
        for name, (forward, x) in networks.items():
            compiled = torch.compile(forward)
            start = time.monotonic()
            compiled_maps = maps_of(compiled(x))
            compile_s = time.monotonic() - start
            compiled_ms = median_cpu_ms(lambda: compiled(x))
            eager_maps, eager_ms = eager[name]
            eager_after_ms = median_cpu_ms(lambda: forward(x))
            same = all(torch.equal(a, b) for a, b in zip(eager_maps, compiled_maps))
            largest = max(float((a - b).abs().max()) for a, b in zip(eager_maps, compiled_maps))
            print(f"{name}: eager {eager_ms:.1f} ms (after compiling: {eager_after_ms:.1f}), compiled {compiled_ms:.1f} ms "
                  f"({eager_ms / compiled_ms:.2f}x); first compiled call {compile_s:.0f} s; maps the same bit for bit: "
                  f"{same} (largest difference {largest:.3g})")


def main() -> None:
    import torch._inductor.config as inductor_config
    inductor_config.freezing = True  # fold the weights into the compiled graph, as an inference-only network allows
    torch.set_num_threads(1)
    torch.manual_seed(0)

    config = SimConfig()
    loop = ClosedLoop(config)
    loop.vehicle.place(loop.scene.stop_line_x_m - 30.0 - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    frame = loop.rig.render_rgb(loop.data, "front")
    loop.close()
    region = regions_px(config.perception, config.camera)["front"]

    arithmetic = auto_arithmetic()
    runner = SignDetectorRunner(SHIPPED_WEIGHTS, num_threads=1, precision=arithmetic)
    x0, y0, x1, y1 = crop_for(region, frame.shape[1], frame.shape[0])  # the front region and its context
    crop = to_tensor(frame[y0:y1, x0:x1]).unsqueeze(0)

    coco = Bf16CenterNet(load_centernet()) if arithmetic == "bf16" else load_centernet()
    upscaled, _ = network_input(image_tensor(frame), "upscale", region, config.perception.coco_upscale)
    print(f"arithmetic: {arithmetic} (auto on this CPU; torch's kernels: {torch.backends.cpu.get_cpu_capability()})")
    compare({f"own detector, {arithmetic}, {x1 - x0}x{y1 - y0} crop": (lambda x: runner._maps(x), crop),
             f"COCO CenterNet, {arithmetic}, {upscaled.shape[3]}x{upscaled.shape[2]} (upscale)": (coco, upscaled)})


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as cache:
        os.environ["TORCHINDUCTOR_CACHE_DIR"] = cache  # a cold cache: the compile time a fresh worker pays
        main()
