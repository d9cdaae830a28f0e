"""One-off probe: what rendering only the perception's region would save, and which pixels it moves.

llvmpipe rasterises every pixel of its framebuffer that a geom covers, whatever is read back. A
framebuffer the size of the region, with the viewport shifted so that the region lands on it,
rasterises only the region. It is not what avsim does, because the pixels are not the same: the
viewport's offset enters the GL's float arithmetic (window x = x_ndc * W/2 + offset), which moves
some vertices by a rounding step and so flips a few edge pixels. avsim instead sets the whole frame
up as before and drops the fragments outside the region with the stencil test
(`OffscreenRenderer._rasterise_only`), which changes no arithmetic. This probe places the car at 40
distances from 120 m to 6 m in each town, renders each camera's default region three ways (the
whole frame shaded with the geoms outside the region culled and the region read back, as avsim did
before the stencil; avsim's way now; the shifted viewport), and prints the CPU time of each and how
many of the region's pixels differ from the first, by how much:

    MUJOCO_GL=egl LP_NUM_THREADS=1 python experiments/probes/crop_render.py

It is not part of avsim; it writes nothing. About a minute.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.sensors.camera import camera_view_option
from avsim.sensors.gl import OffscreenRenderer, context_with_framebuffer
from avsim.sensors.regions import deployed_region_px
from avsim.vehicle.physics import FRONT_BUMPER_X_M

DISTANCES_M = np.linspace(120.0, 6.0, 40)


class CropRenderer:
    """A framebuffer of the region's size; the frame's viewport shifted so the region lands on it."""

    def __init__(self, model: mujoco.MjModel, frame_px: tuple[int, int], region_px: tuple[int, int, int, int]) -> None:
        width, height = frame_px
        x0, y0, x1, y1 = region_px
        self._gl = mujoco.GLContext(x1 - x0, y1 - y0)
        self._gl.make_current()
        self._con = context_with_framebuffer(model, x1 - x0, y1 - y0)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        self._viewport = mujoco.MjrRect(-x0, -(height - y1), width, height)
        self._read = mujoco.MjrRect(0, 0, x1 - x0, y1 - y0)
        self._buffer = np.empty((y1 - y0, x1 - x0, 3), np.uint8)

    def render(self, scene: mujoco.MjvScene) -> np.ndarray:
        self._gl.make_current()
        mujoco.mjr_render(self._viewport, scene, self._con)
        mujoco.mjr_readPixels(self._buffer, None, self._read, self._con)
        return self._buffer[::-1]

    def close(self) -> None:
        self._gl.make_current()
        self._con.free()
        self._gl.free()


def measure(town: str) -> None:
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}}))
    config = loop.config.camera
    frame_px = (config.width_px, config.height_px)
    option = camera_view_option()
    whole = OffscreenRenderer(loop.model, *frame_px, segmentation=False)
    whole.rasterise_region_only = False
    masked = OffscreenRenderer(loop.model, *frame_px, segmentation=False)
    for camera in ("front", "side"):
        region = deployed_region_px(camera, config)
        x0, y0, x1, y1 = region
        camera_id = loop.model.camera(f"car/{camera}").id
        crop = CropRenderer(loop.model, frame_px, region)
        scene = mujoco.MjvScene(loop.model, maxgeom=10000)
        free_camera = mujoco.MjvCamera()
        free_camera.type, free_camera.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, camera_id
        times_ms = {"whole": [], "stencil": [], "crop": []}
        differing, worst, stencil_differing = [], 0, 0
        for dist_m in DISTANCES_M:
            loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
            mujoco.mj_forward(loop.model, loop.data)
            start = time.process_time()
            reference = whole.render(loop.data, camera_id, option, region).copy()
            times_ms["whole"].append(1e3 * (time.process_time() - start))
            start = time.process_time()
            stencilled = masked.render(loop.data, camera_id, option, region)
            times_ms["stencil"].append(1e3 * (time.process_time() - start))
            stencil_differing += int((stencilled != reference).any(axis=2).sum())
            start = time.process_time()
            mujoco.mjv_updateScene(loop.model, loop.data, option, mujoco.MjvPerturb(), free_camera,
                                   mujoco.mjtCatBit.mjCAT_ALL, scene)
            cropped = crop.render(scene)
            times_ms["crop"].append(1e3 * (time.process_time() - start))
            diff = np.abs(reference.astype(int) - cropped.astype(int)).max(axis=2)
            differing.append(int((diff > 0).sum()))
            worst = max(worst, int(diff.max()))
        crop.close()
        print(f"{town} {camera} region {list(region)}: whole frame shaded {np.median(times_ms['whole']):.2f} ms, "
              f"stencil {np.median(times_ms['stencil']):.2f} ms ({stencil_differing} pixels differ in all), "
              f"crop {np.median(times_ms['crop']):.2f} ms (medians of {len(DISTANCES_M)}); pixels the crop changes per "
              f"frame: median {int(np.median(differing))}, max {max(differing)} of {(x1 - x0) * (y1 - y0)}, "
              f"by at most {worst} levels")
    whole.close()
    masked.close()
    loop.close()


def main() -> None:
    for town in ("town07", "town03", "town10"):
        measure(town)


if __name__ == "__main__":
    main()
