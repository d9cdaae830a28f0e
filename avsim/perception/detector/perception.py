"""`detector` perception: the trained sign detector run on the camera's rendered RGB frame."""

from __future__ import annotations

from pathlib import Path

import mujoco

from avsim.perception.base import Detection, Perception
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.sensors.camera import CameraRig
from avsim.sensors.noise import SensorNoise

# The shipped weights, trained by `avsim detector train` on `avsim detector make-data` renders.
SHIPPED_WEIGHTS = Path(__file__).resolve().parents[3] / "models" / "sign_detector.pt"


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
    sensor noise before the network sees it.
    """

    name = "detector"

    def __init__(self, weights_path: str, min_confidence: float, min_box_height_px: float = 1.0, threads: int = 1,
                 noise: SensorNoise | None = None) -> None:
        self.runner = SignDetectorRunner(resolve_weights_path(weights_path), conf_threshold=min_confidence, num_threads=threads)
        self.min_box_height_px = min_box_height_px
        self.noise = noise

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        frame = rig.render_rgb(data, camera)
        if self.noise is not None:
            frame = self.noise.apply(frame)
        detections = self.runner.detect(frame, camera)
        return [d for d in detections if d.height_px >= self.min_box_height_px]
