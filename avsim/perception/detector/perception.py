"""`detector` perception: the trained sign detector run on the camera's rendered RGB frame."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import mujoco
import numpy as np
import torch

from avsim.perception.base import Detection, Perception
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.sensors.camera import CameraRig
from avsim.sensors.noise import SensorNoise

# The shipped weights, trained by `avsim detector train` on `avsim detector make-data` renders.
SHIPPED_WEIGHTS = Path(__file__).resolve().parents[3] / "models" / "sign_detector.pt"

Region = tuple[int, int, int, int]


def resolve_weights_path(weights_path: str) -> Path:
    """The configured weights file; an empty string means the shipped weights."""
    return Path(weights_path) if weights_path else SHIPPED_WEIGHTS


class DetectorPerception(Perception):
    """Renders the camera's RGB frame and runs the detector on its pixels.

    Every detection at or above `min_confidence` is reported; the braking policy
    applies its own, higher threshold, so a run's records also show the weak
    detections an attack leaves behind. Boxes shorter than `min_box_height_px` are
    dropped, as the oracle drops them: the same range for both perceptions (see
    `PerceptionConfig.min_box_height_px`). With `noise`, each frame gets the run's seeded
    sensor noise before the network sees it. `regions_px` maps a camera to its region of
    interest (x0, y0, x1, y1) [px] (`SignDetectorRunner.detect`); a camera without one is
    searched whole.

    With one torch thread and several cameras, `detect_cameras` renders every camera first
    (the rasteriser then has both cores), then runs the last camera's network on this thread
    while the others run on a worker thread. Each network still runs single-threaded, so the
    scores are the same bit for bit as one camera after the other.
    """

    name = "detector"

    def __init__(self, weights_path: str, min_confidence: float, min_box_height_px: float = 1.0, threads: int = 1,
                 noise: SensorNoise | None = None, regions_px: dict[str, Region] | None = None) -> None:
        self.runner = SignDetectorRunner(resolve_weights_path(weights_path), conf_threshold=min_confidence, num_threads=threads)
        self.min_box_height_px = min_box_height_px
        self.noise = noise
        self.regions_px = dict(regions_px or {})
        self.threads = threads
        self._worker: ThreadPoolExecutor | None = None

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        return self._network(self._frame(rig, data, camera), camera)

    def detect_cameras(self, rig: CameraRig, data: mujoco.MjData, cameras: tuple[str, ...]) -> dict[str, list[Detection]]:
        if self.threads != 1 or len(cameras) < 2:
            return super().detect_cameras(rig, data, cameras)
        if self._worker is None:
            # torch's thread count is per OS thread under OpenMP: set it in the worker too.
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="avsim-detector",
                                              initializer=torch.set_num_threads, initargs=(1,))
        # Frames render (GL is bound to this thread) and take their noise in camera order,
        # so the noise stream is drawn exactly as in sequential detection.
        frames = {camera: self._frame(rig, data, camera) for camera in cameras}
        pending = {camera: self._worker.submit(self._network, frames[camera], camera) for camera in cameras[:-1]}
        last = cameras[-1]
        last_detections = self._network(frames[last], last)
        return {camera: (last_detections if camera == last else pending[camera].result()) for camera in cameras}

    def _frame(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> np.ndarray:
        frame = rig.render_rgb(data, camera)
        return frame if self.noise is None else self.noise.apply(frame)

    def _network(self, frame: np.ndarray, camera: str) -> list[Detection]:
        detections = self.runner.detect(frame, camera, region_px=self.regions_px.get(camera))
        return [d for d in detections if d.height_px >= self.min_box_height_px]

    def close(self) -> None:
        if self._worker is not None:
            self._worker.shutdown()
            self._worker = None
