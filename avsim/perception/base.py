"""The perception interface and its typed detection record."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import mujoco

from avsim.sensors.camera import CameraRig

SIGN_CLASSES = ("stop_sign", "yield", "speed_limit")


@dataclass(frozen=True)
class Detection:
    """One detected sign.

    box_xyxy_px: (x0, y0, x1, y1) in the camera's image, continuous pixel coordinates.
    camera: which car camera saw it ("front" or "side").
    truncated: the box touches the image border, so part of the sign may be cut off
    and its height is not a safe basis for a range estimate.
    source: which network reported it, in a perception that runs several (`ensemble`:
    "detector", "coco", or "detector+coco" for a stop sign both confirmed); "" otherwise.
    """

    class_name: str
    confidence: float
    box_xyxy_px: tuple[float, float, float, float]
    camera: str
    truncated: bool = False
    source: str = ""

    @property
    def height_px(self) -> float:
        """Box height [px] in the camera image: y1 - y0 of `box_xyxy_px` (what the pinhole range reads)."""
        return self.box_xyxy_px[3] - self.box_xyxy_px[1]


def touches_border(box_xyxy_px: tuple[float, float, float, float], width_px: int, height_px: int, tol_px: float = 1.0) -> bool:
    """Whether a box lies within `tol_px` of the image border."""
    x0, y0, x1, y1 = box_xyxy_px
    return x0 <= tol_px or y0 <= tol_px or x1 >= width_px - tol_px or y1 >= height_px - tol_px


class Perception(ABC):
    """Detects signs in one camera at the current simulation state.

    Implementations render what they need through the `CameraRig` (segmentation for
    the oracle, RGB for a learned detector), so a run renders nothing it does not use.
    """

    name: str

    @abstractmethod
    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        """Detections in `camera`'s view, highest confidence first."""

    def detect_cameras(self, rig: CameraRig, data: mujoco.MjData, cameras: tuple[str, ...]) -> dict[str, list[Detection]]:
        """`detect` for each camera, in order; implementations may overlap the cameras' work
        as long as the result is the same."""
        return {camera: self.detect(rig, data, camera) for camera in cameras}

    def close(self) -> None:
        """Release what the perception holds (threads, contexts); the default holds nothing."""


class NoPerception(Perception):
    """`none`: sees nothing, renders nothing. For whatever decides without a perception: the
    autopilot (it reads the map) or a Gymnasium agent built with `perception=None` (`avsim.gym`)."""

    name = "none"

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        """No detections, whatever the camera sees."""
        return []
