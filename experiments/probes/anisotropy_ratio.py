"""Does llvmpipe's anisotropic filtering follow the ratio asked for, and where does its time go?

Renders the front camera of one scene draw (textured materials, no sensor noise) at a few distances before
the sign under `camera.texture_anisotropy` = 1, 2, 4, 8 and 16, and prints for each ratio the render's CPU time
(median over the distances, each rendered `--repeats` times) and how many pixels differ from the 16:1 frame
and from the next lower ratio's. A GL that clamps the footprint at N:1 gives fewer changed pixels, and less
time, the closer N gets to 16; one that ignores N gives the same pixels at every N > 1.

    MUJOCO_GL=egl LP_NUM_THREADS=1 python experiments/probes/anisotropy_ratio.py --town town10
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from avsim.config import with_overrides
from avsim.realism.frame_set import scene_config, scene_draws
from avsim.realism.settings import SETTINGS
from avsim.sensors.camera import CameraRig
from avsim.vehicle.physics import Vehicle
from avsim.world.scene import compose_scene

RATIOS = (1, 2, 4, 8, 16)


def render_at_ratio(town: str, ratio: int, dists_m: tuple[float, ...], repeats: int) -> tuple[list[np.ndarray], float]:
    """Front frames (H, W, 3) uint8 at each distance [m] before the sign face, and the median CPU
    seconds a render (this process's, GL threads included)."""
    scene = scene_draws((town,), 1, 0)[0]
    config = with_overrides(scene_config(scene, SETTINGS["textured"]), {"camera": {"texture_anisotropy": ratio}})
    spec, info = compose_scene(config)
    model = spec.compile()
    data = mujoco.MjData(model)
    vehicle = Vehicle(model, data, config.vehicle)
    rig = CameraRig(model, config.camera)
    cam_x_m = float(model.cam_pos[model.camera("car/front").id][0])
    images, cpu_s = [], []
    try:
        for dist_m in dists_m:
            vehicle.place(info.stop_sign.face_center_m[0] - dist_m - cam_x_m, info.layout.lane_center_y_m, 0.0, 0.0)
            for _ in range(repeats):
                start = time.process_time()
                image = rig.render_rgb(data, "front")
                cpu_s.append(time.process_time() - start)
            images.append(image)
    finally:
        rig.close()
    return images, float(np.median(cpu_s))


def changed(a: list[np.ndarray], b: list[np.ndarray]) -> tuple[int, int]:
    """(pixels that differ in any channel, summed over the frames; the largest difference in levels)."""
    diffs = [np.abs(x.astype(np.int16) - y.astype(np.int16)) for x, y in zip(a, b)]
    return int(sum((d.max(axis=2) > 0).sum() for d in diffs)), int(max(d.max() for d in diffs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--town", default="town10")
    parser.add_argument("--dists-m", default="15,30,45", help="comma-separated distances before the sign [m]")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    dists_m = tuple(float(d) for d in args.dists_m.split(","))
    frames = {}
    for ratio in RATIOS:
        frames[ratio], cpu_s = render_at_ratio(args.town, ratio, dists_m, args.repeats)
        print(f"{args.town} anisotropy {ratio:2d}: {cpu_s * 1000:8.1f} ms CPU a frame (median)", flush=True)
    pixels = frames[1][0].shape[0] * frames[1][0].shape[1] * len(dists_m)
    for lower, higher in zip(RATIOS, RATIOS[1:]):
        n, most = changed(frames[lower], frames[higher])
        print(f"  {lower:2d} -> {higher:2d}: {n:7d} of {pixels} pixels differ (largest {most} levels)")
    for ratio in RATIOS[:-1]:
        n, most = changed(frames[ratio], frames[16])
        print(f"  {ratio:2d} vs 16: {n:7d} of {pixels} pixels differ (largest {most} levels)")


if __name__ == "__main__":
    main()
