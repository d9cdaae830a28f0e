"""`detector` perception: the trained sign detector run on the camera's rendered RGB frame."""

from __future__ import annotations

from pathlib import Path

import mujoco

from avsim.perception.base import Detection, Perception
from avsim.perception.detector.infer import SignDetectorRunner
from avsim.sensors.camera import CameraRig

# The shipped weights, trained by `avsim detector train` on `avsim detector make-data` renders.
SHIPPED_WEIGHTS = Path(__file__).resolve().parents[3] / "models" / "sign_detector.pt"


def resolve_weights_path(weights_path: str) -> Path:
    """The configured weights file; an empty string means the shipped weights."""
    return Path(weights_path) if weights_path else SHIPPED_WEIGHTS


class DetectorPerception(Perception):
    """Renders the camera's RGB frame and runs the detector on its pixels.

    Every detection at or above `min_confidence` is reported; the braking policy
    applies its own, higher threshold, so a run's records also show the weak
    detections an attack leaves behind.
    """

    name = "detector"

    def __init__(self, weights_path: str, min_confidence: float) -> None:
        self.runner = SignDetectorRunner(resolve_weights_path(weights_path), conf_threshold=min_confidence)

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        return self.runner.detect(rig.render_rgb(data, camera), camera)
