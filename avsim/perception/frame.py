"""A perception that runs a detector on each camera's rendered RGB frame.

`FramePerception` does what every pixel-based perception needs around its network: render
the frame, add the run's seeded sensor noise, run the detector on the camera's region of
interest, drop boxes shorter than the range limit. The detector is anything with
`detect(image_rgb, camera, region_px) -> list[Detection]` (avsim's own sign detector, the COCO
CenterNet, an ONNX model). With one torch thread and two cameras, the cameras' networks run at once on two
threads (each still single-threaded, so the result is the same, bit for bit, as one camera
after the other); the frames render, and draw their noise, in camera order first.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Protocol

import mujoco
import numpy as np
import torch

from avsim.perception.base import Detection, Perception
from avsim.sensors.camera import CameraRig
from avsim.sensors.noise import SensorNoise

Region = tuple[int, int, int, int]


class FrameDetector(Protocol):
    def detect(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None) -> list[Detection]: ...


class FramePerception(Perception):
    """Renders each camera's RGB frame and reports what `detector` finds in it.

    min_box_height_px: boxes shorter than this are dropped (`PerceptionConfig.min_box_height_px`).
    regions_px: camera -> region of interest (x0, y0, x1, y1) [px]; a camera without one
    is searched whole. threads: the torch thread count (a process-wide setting).
    """

    def __init__(self, name: str, detector: FrameDetector, min_box_height_px: float, threads: int,
                 noise: SensorNoise | None, regions_px: dict[str, Region] | None = None) -> None:
        self.name = name
        self.detector = detector
        self.min_box_height_px = min_box_height_px
        self.threads = threads
        self.noise = noise
        self.regions_px = dict(regions_px or {})
        self._worker: ThreadPoolExecutor | None = None
        torch.set_num_threads(threads)

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        return self._network(self._frame(rig, data, camera), camera)

    def detect_cameras(self, rig: CameraRig, data: mujoco.MjData, cameras: tuple[str, ...]) -> dict[str, list[Detection]]:
        if self.threads != 1 or len(cameras) < 2:
            return super().detect_cameras(rig, data, cameras)
        if self._worker is None:
            # torch's thread count is per OS thread under OpenMP: set it in the worker too.
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"avsim-{self.name}",
                                              initializer=torch.set_num_threads, initargs=(1,))
        frames = {camera: self._frame(rig, data, camera) for camera in cameras}
        pending = {camera: self._worker.submit(self._network, frames[camera], camera) for camera in cameras[:-1]}
        last = cameras[-1]
        last_detections = self._network(frames[last], last)
        return {camera: (last_detections if camera == last else pending[camera].result()) for camera in cameras}

    def _frame(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> np.ndarray:
        frame = rig.render_rgb(data, camera)
        return frame if self.noise is None else self.noise.apply(frame)

    def _network(self, frame: np.ndarray, camera: str) -> list[Detection]:
        detections = self.detector.detect(frame, camera, region_px=self.regions_px.get(camera))
        return [d for d in detections if d.height_px >= self.min_box_height_px]

    def close(self) -> None:
        if self._worker is not None:
            self._worker.shutdown()
            self._worker = None
