"""`avsim bench`: physics, rendering and closed-loop speed on this machine.

Prints measured figures only; targets are stated beside them for comparison, and
nothing here asserts. Run with `avsim bench` or `python -m avsim.bench`.
"""

from __future__ import annotations

import time

import mujoco

from avsim.config import COCO_INPUTS, SimConfig, with_overrides
from avsim.bench.gym_env import print_env_rows, print_vector_rows
from avsim.loop import ClosedLoop
from avsim.perception.cpu_bf16 import arithmetics_here
from avsim.perception.factory import build_frame_detector, network_arithmetic
from avsim.runner import run_config
from avsim.sensors.regions import regions_px
from avsim.vehicle.physics import FRONT_BUMPER_X_M, Controls


def _physics_steps_per_s(config: SimConfig, steps: int, controls: Controls | None = None) -> float:
    """MuJoCo steps per second of the car in the town: bare `mj_step` (controls None), or
    through `Vehicle.advance` with the tyre model, anti-lock brakes and traction control
    running at every step under `controls`."""
    loop = ClosedLoop(config)
    loop.vehicle.place(-250.0, loop.scene.layout.lane_center_y_m, 0.0, 25.0)
    start = time.perf_counter()
    if controls is None:
        mujoco.mj_step(loop.model, loop.data, nstep=steps)
    else:
        substeps = config.loop.substeps
        for _ in range(steps // substeps):
            loop.vehicle.apply(controls)
            loop.vehicle.advance(substeps)
    rate = steps / (time.perf_counter() - start)
    loop.close()
    return rate


def _frames_per_s(config: SimConfig, frames: int, segmentation: bool) -> float:
    loop = ClosedLoop(config)
    loop.vehicle.place(-200.0, loop.scene.layout.lane_center_y_m, 0.0, 20.0)
    render = (lambda: loop.rig.render_segmentation(loop.data, "front")) if segmentation else (lambda: loop.rig.render_rgb(loop.data, "front"))
    render()  # context creation is not part of the frame rate
    elapsed = 0.0
    for _ in range(frames):
        # Move the car between frames: an unchanged scene can be served from caches.
        mujoco.mj_step(loop.model, loop.data, nstep=25)
        start = time.perf_counter()
        render()
        elapsed += time.perf_counter() - start
    loop.close()
    return frames / elapsed


def _detector_ms_per_frame(config: SimConfig, frames: int, threads: int,
                           region_px: tuple[int, int, int, int] | None = None) -> tuple[float, float]:
    """Median and 90th-percentile detector time [ms] on rendered front-camera frames
    (pre-processing, network and NMS; rendering excluded) with `threads` torch threads,
    on the whole frame or on a region of interest (`region_px`)."""
    from avsim.perception.detector.infer import SignDetectorRunner
    from avsim.perception.detector.weights import resolve_weights_path

    detector = SignDetectorRunner(resolve_weights_path(config.perception.weights_path),
                                  conf_threshold=config.perception.min_confidence, num_threads=threads)
    return _ms_per_frame(detector, _approach_frames(config), frames, region_px)


def _approach_frames(config: SimConfig, count: int = 16) -> list:
    """Front-camera frames along the approach (80 m to 8 m), so boxes of every size (and none) are in the mix."""
    import numpy as np

    loop = ClosedLoop(with_overrides(config, {"perception": {"kind": "oracle"}}))
    images = []
    for dist_m in np.linspace(80.0, 8.0, count):
        loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        images.append(loop.rig.render_rgb(loop.data, "front"))
    loop.close()
    return images


def _coco_ms_per_frame(config: SimConfig, frames: int, mode: str, precision: str) -> tuple[float, float]:
    """Median and 90th-percentile COCO CenterNet time [ms] per front-camera frame at perception.threads,
    as deployed: input preparation by `mode`, the network at `precision`, decoding, mapping and NMS
    (rendering excluded)."""
    detector = build_frame_detector(with_overrides(config.perception, {"kind": "coco", "coco_input": mode,
                                                                        "coco_precision": precision}))
    return _ms_per_frame(detector, _approach_frames(config), frames, regions_px(config.perception, config.camera)["front"])


def _yolo_rows(config: SimConfig, frames: int) -> None:
    """YOLOv3-tiny (--perception yolo) per front-camera frame at perception.threads, at each input and
    precision, as deployed: input, network, decoding, mapping and NMS (rendering excluded)."""
    default = (config.perception.yolo_input, network_arithmetic(config.perception, "yolo"))
    for yolo_input in COCO_INPUTS:
        for yolo_precision in arithmetics_here():
            detector = build_frame_detector(with_overrides(config.perception, {"kind": "yolo", "yolo_input": yolo_input,
                                                                                "yolo_precision": yolo_precision}))
            median_ms, p90_ms = _ms_per_frame(detector, _approach_frames(config), frames, regions_px(config.perception, config.camera)["front"])
            label = f"{yolo_input} {yolo_precision}" + (" (default)" if (yolo_input, yolo_precision) == default else "")
            print(f"  yolo, {label:24s} {config.perception.threads} thread  {median_ms:6.1f} ms median"
                  f"    (90th percentile {p90_ms:.1f} ms)")


def _ms_per_frame(detector, images: list, frames: int, region_px: tuple[int, int, int, int] | None) -> tuple[float, float]:
    """Median and 90th percentile [ms] of `detector.detect` over `frames` calls cycling through `images`."""
    import numpy as np

    for image in images[:5]:  # warm-up: first calls allocate (and build oneDNN kernels)
        detector.detect(image, "front", region_px=region_px)
    times_ms = []
    for i in range(frames):
        start = time.perf_counter()
        detector.detect(images[i % len(images)], "front", region_px=region_px)
        times_ms.append(1e3 * (time.perf_counter() - start))
    return float(np.median(times_ms)), float(np.percentile(times_ms, 90))


def _purify_ms_per_frame(config: SimConfig, frames: int, purify: str) -> tuple[float, float]:
    """Median and 90th-percentile time [ms] of the input purification (`perception.purify`) of one
    whole 640x480 front-camera frame, the work it adds in front of the network."""
    import numpy as np

    from avsim.perception.purify import build_purifier

    purifier = build_purifier(with_overrides(config.perception, {"purify": purify}))
    images = _approach_frames(config)
    times_ms = []
    for i in range(frames):
        start = time.perf_counter()
        purifier(images[i % len(images)])
        times_ms.append(1e3 * (time.perf_counter() - start))
    return float(np.median(times_ms)), float(np.percentile(times_ms, 90))


def _closed_loop_rows(base: SimConfig, perception: str, towns: tuple[str, ...], target: str,
                      cameras: tuple[tuple[str, str], ...] = (("one camera (baseline)", "baseline"),
                                                             ("two cameras (side_camera)", "side_camera"))) -> None:
    for town in towns:
        for label, policy in cameras:
            config = with_overrides(base, {"scenario": {"town": town}, "policy": {"name": policy}, "perception": {"kind": perception}})
            result, wall_s = run_config(config)
            print(f"  closed loop, {perception:8s} {town}, {label:26s} {result.sim_time_s / wall_s:5.1f}x real time "
                  f"({result.sim_time_s:.1f} s simulated in {wall_s:.1f} s; {target})")


def run_benchmarks(quick: bool = False) -> None:
    """Print `avsim bench`'s table: physics, rendering, detector latency, closed-loop and Gymnasium
    speed on this machine (fewer repetitions with `quick`).
    """
    base = SimConfig()
    frames = 50 if quick else 200
    print(f"avsim bench ({'quick' if quick else 'full'}): {base.camera.width_px}x{base.camera.height_px}, "
          f"physics dt {base.loop.physics_dt_s} s, control dt {base.loop.control_dt_s} s")
    steps = 20000 if quick else 100000
    rate = _physics_steps_per_s(base, steps)
    print(f"  physics                          {rate:10.0f} steps/s        (target >= 50000; bare mj_step, car with suspension)")
    cruise = _physics_steps_per_s(base, steps // 4, Controls(throttle=0.2))
    print(f"  physics, cruising                {cruise:10.0f} steps/s        (tyre model and traction control at every step)")
    braking = _physics_steps_per_s(base, steps // 20, Controls(brake=1.0))
    print(f"  physics, full brake              {braking:10.0f} steps/s        (tyre model and anti-lock brakes at every step)")
    print(f"  front camera RGB render          {_frames_per_s(base, frames, False):10.1f} frames/s       (target >= 40)")
    print(f"  front camera full segmentation   {_frames_per_s(base, frames, True):10.1f} frames/s       "
          f"({base.camera.seg_supersample}x supersampled, whole image decoded)")
    _closed_loop_rows(base, "oracle", ("town07", "town10"), "target >= 3 for one camera")
    no_abs = with_overrides(base, {"vehicle": {"abs_enabled": False, "traction_control_enabled": False}})
    _closed_loop_rows(no_abs, "oracle", ("town07",), "the same run without anti-lock brakes or traction control",
                      (("one camera, no ABS or TCS", "baseline"),))
    # The Gymnasium environment against the closed loop it drives (avsim/bench/gym_env.py).
    print_env_rows(base, ("oracle",) if quick else ("oracle", "detector"), repeats=1 if quick else 3)
    print_vector_rows((1, 8) if quick else (1, 8, 32), steps=10 if quick else 20)
    # The runs use perception.threads (1 by default: bit-identical everywhere, and a pool of
    # single-threaded workers fills the cores); 2 threads is what one run alone could use.
    roi = regions_px(base.perception, base.camera)["front"]
    for threads in sorted({base.perception.threads, 2}):
        for label, region in ((f"whole {base.camera.width_px}x{base.camera.height_px} frame", None), (f"front region {list(roi)}", roi)):
            median_ms, p90_ms = _detector_ms_per_frame(base, 50 if quick else 200, threads, region)
            print(f"  detector, {label:33s} {threads} thread{'s' if threads > 1 else ' '} {median_ms:6.1f} ms median"
                  f"    (90th percentile {p90_ms:.1f} ms; target <= 12)")
    target = "target >= 3 with one camera, >= 2 with two"
    _closed_loop_rows(base, "detector", ("town07",) if quick else ("town07", "town10"), target)
    two_threads = with_overrides(base, {"perception": {"threads": 2}})
    _closed_loop_rows(two_threads, "detector", ("town07",) if quick else ("town07", "town10"), target,
                      (("one camera, 2 threads", "baseline"), ("two cameras, 2 threads", "side_camera")))
    _closed_loop_rows(with_overrides(two_threads, {"vehicle": {"abs_enabled": False, "traction_control_enabled": False}}),
                      "detector", ("town07",), "the same run without anti-lock brakes or traction control",
                      (("one camera, 2 threads, no ABS/TCS", "baseline"),))
    # The COCO CenterNet (--perception coco), at perception.threads (1) on the front region of interest.
    mode, precision = base.perception.coco_input, network_arithmetic(base.perception, "coco")
    settings = [(mode, p) for p in (precision, *(p for p in arithmetics_here() if p != precision))]
    settings += [(m, precision) for m in COCO_INPUTS if m != mode]
    for coco_input, coco_precision in settings:
        median_ms, p90_ms = _coco_ms_per_frame(base, 20 if quick else 100, coco_input, coco_precision)
        default = " (default)" if (coco_input, coco_precision) == (mode, precision) else ""
        print(f"  coco, {coco_input} {coco_precision}{default:10s} {base.perception.threads} thread  {median_ms:6.1f} ms median"
              f"    (90th percentile {p90_ms:.1f} ms; target <= 15)")
    _closed_loop_rows(base, "coco", ("town07",) if quick else ("town07", "town10"), target)
    _yolo_rows(base, 20 if quick else 100)
    _closed_loop_rows(base, "yolo", ("town07",), target)
    # The defences' own cost (the leaderboard's cost column): purification per frame, and the ensemble
    # perception (the own detector and the COCO CenterNet on every frame) in the loop.
    for purify in ("jpeg", "median"):
        median_ms, p90_ms = _purify_ms_per_frame(base, frames, purify)
        print(f"  purify={purify:6s} whole 640x480 frame         {median_ms:6.1f} ms median    (90th percentile {p90_ms:.1f} ms)")
    _closed_loop_rows(base, "ensemble", ("town07",), "both networks on every frame",
                      (("one camera (baseline)", "baseline"),))
