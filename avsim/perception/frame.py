"""A perception that runs a detector on each camera's rendered RGB frame.

`FramePerception` does what every pixel-based perception needs around its network: render
the frame, add the run's seeded sensor noise, run the detector on the camera's region of
interest, drop boxes shorter than the range limit. The detector is anything with
`detect(image_rgb, camera, region_px) -> list[Detection]` (avsim's own sign detector, the COCO
CenterNet, an ONNX model). With one torch thread and two cameras, the cameras' networks run at once on two
threads (each still single-threaded, so the result is the same, bit for bit, as one camera
after the other); the frames render, and draw their noise, in camera order first.

A detector that reads only part of a frame says which (`pixels_needed`, e.g. the own detector's
crop around the region of interest): then only that part is read back from the renderer and
noised, with the same pixel values as in a whole frame. The lock-step batch
(`avsim.lockstep`) calls the two halves of `detect_cameras` itself, `frame_requests`
then `keep`, to run many cars' frames through one network call (`detect_many`).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any, Protocol

import mujoco
import numpy as np
import torch

from avsim.perception.base import Detection, Perception
from avsim.sensors.camera import CameraRig
from avsim.sensors.noise import SensorNoise

Region = tuple[int, int, int, int]


class FrameDetector(Protocol):
    """What a pixel perception's network offers. Optional, where the detector can do better than the
    defaults: `pixels_needed(region_px, width_px, height_px) -> Region | None` (the part of a frame it
    reads; None: all of it), `detect_many([(image_rgb, camera, region_px), ...]) -> [detections, ...]`
    (each frame's detections exactly as `detect` gives them alone), and `detect_members` with `fuse` (an
    ensemble: its networks' detections, then its own fusion of them; `detect_parts_many`)."""

    def detect(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None) -> list[Detection]:
        """Detections in `image_rgb` (H, W, 3) uint8 RGB, boxes in its pixels; with `region_px`
        (x0, y0, x1, y1) only boxes centred inside that region.
        """


# (frame (H, W, 3) uint8, camera name, region of interest or None): one frame for a detector.
FrameRequest = tuple[np.ndarray, str, Region | None]


def detect_many(detector: FrameDetector, requests: list[FrameRequest]) -> list[list[Detection]]:
    """The detector's detections of each requested frame: its own `detect_many` where it has one."""
    if hasattr(detector, "detect_many"):
        return detector.detect_many(requests)
    return [detector.detect(frame, camera, region_px=region) for frame, camera, region in requests]


def detect_parts_many(detector: FrameDetector, requests: list[FrameRequest]) -> list[Any]:
    """What the detector's networks find in each requested frame before anything that detectors sharing
    those networks do differently (an ensemble's fusion: `detect_members`); `detections_from_parts`
    turns each into the detector's detections. Otherwise the detections themselves (`detect_many`)."""
    if hasattr(detector, "detect_members"):
        return [detector.detect_members(frame, camera, region_px=region) for frame, camera, region in requests]
    return detect_many(detector, requests)


def detections_from_parts(detector: FrameDetector, parts: Any) -> list[Detection]:
    """The detections `detector` gives a frame from `detect_parts_many`'s parts of it (its own or those of a
    detector with the same networks): an ensemble fuses them by its own rule. Keyed on `detect_members`, as
    `detect_parts_many` is, not on `fuse`: the own detector's torch model has a `fuse` of another meaning."""
    return detector.fuse(parts) if hasattr(detector, "detect_members") else parts


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
        """The detections of `camera`'s frame at the state `data` holds: rendered, noised, detected, range-limited."""
        return self._network(self._frame(rig, data, camera), camera)

    def frame_requests(self, rig: CameraRig, data: mujoco.MjData, cameras: tuple[str, ...]) -> list[FrameRequest]:
        """Render (and noise) each camera's frame, in camera order: what the detector is to look at."""
        return [(self._frame(rig, data, camera), camera, self.regions_px.get(camera)) for camera in cameras]

    def keep(self, detections: list[Detection]) -> list[Detection]:
        """The detections this perception reports of those its detector found in a frame (the range limit)."""
        return [d for d in detections if d.height_px >= self.min_box_height_px]

    def detect_cameras(self, rig: CameraRig, data: mujoco.MjData, cameras: tuple[str, ...]) -> dict[str, list[Detection]]:
        """Each camera's detections; with one thread and several cameras, the last camera's network runs
        here while a worker thread runs the others (the same results as one after another).
        """
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
        needed = self._pixels_needed(rig, camera)
        return rig.render_rgb(data, camera, needed, noise=self.noise)

    def _pixels_needed(self, rig: CameraRig, camera: str) -> Region | None:
        if not hasattr(self.detector, "pixels_needed"):
            return None
        intrinsics = rig.intrinsics(camera)
        return self.detector.pixels_needed(self.regions_px.get(camera), intrinsics.width_px, intrinsics.height_px)

    def _network(self, frame: np.ndarray, camera: str) -> list[Detection]:
        return self.keep(self.detector.detect(frame, camera, region_px=self.regions_px.get(camera)))

    def close(self) -> None:
        """Stop the worker thread, if one was started."""
        if self._worker is not None:
            self._worker.shutdown()
            self._worker = None
