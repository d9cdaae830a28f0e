"""What the agent of `avsim/StopSign-v0` observes, as a Gymnasium `Dict` space.

Keys (CAMERA is each camera the environment was built with, "front" and/or "side"):

    speed_mps           (1,) float32   the car's forward speed [m/s] (odometry; negative rolling back)
    image_CAMERA        (H, W, 3) uint8 the camera's RGB render, row 0 at the top (with images=True)
    detections_CAMERA   (8, 6) float32 the perception's detections in that camera (with a perception)

A detections row is [class, confidence, x0, y0, x1, y1]: the box in the camera's pixels
(clipped to the image), its confidence in [0, 1] and a class id:

    0  empty row (the array is zero-padded)
    1  stop_sign     2  yield     3  speed_limit
    4  any other class (the COCO CenterNet's 79 other classes, an ONNX model's own)

Rows hold the sign classes (1-3) first, then the others, each most confident first; beyond
MAX_DETECTIONS they are dropped. Nothing privileged is observed: the distance to the stop line
and the car's position are in `info` only, for evaluation.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from avsim.config import CameraConfig
from avsim.loop import MAX_PLAUSIBLE_SPEED_MPS
from avsim.perception.base import SIGN_CLASSES, Detection

MAX_DETECTIONS = 8
EMPTY_CLASS_ID = 0
CLASS_IDS = {name: i + 1 for i, name in enumerate(SIGN_CLASSES)}  # stop_sign 1, yield 2, speed_limit 3
OTHER_CLASS_ID = len(SIGN_CLASSES) + 1


def class_id(class_name: str) -> int:
    """The observation's id of a detection class (see the module docstring)."""
    return CLASS_IDS.get(class_name, OTHER_CLASS_ID)


def observation_space(cameras: tuple[str, ...], images: bool, detections: bool, camera: CameraConfig) -> spaces.Dict:
    """The `Dict` space for these cameras, with images and/or detections, at `camera`'s resolution."""
    width, height = camera.width_px, camera.height_px
    entries: dict[str, spaces.Space] = {
        # The loop stops a run as diverged beyond this speed, so it bounds the observation too.
        "speed_mps": spaces.Box(-MAX_PLAUSIBLE_SPEED_MPS, MAX_PLAUSIBLE_SPEED_MPS, (1,), np.float32),
    }
    high = np.array([OTHER_CLASS_ID, 1.0, width, height, width, height], np.float32)
    for name in cameras:
        if images:
            entries[f"image_{name}"] = spaces.Box(0, 255, (height, width, 3), np.uint8)
        if detections:
            entries[f"detections_{name}"] = spaces.Box(np.zeros((MAX_DETECTIONS, 6), np.float32),
                                                       np.tile(high, (MAX_DETECTIONS, 1)), dtype=np.float32)
    return spaces.Dict(entries)


def detections_array(detections: list[Detection], width_px: int, height_px: int) -> np.ndarray:
    """(MAX_DETECTIONS, 6) float32 rows [class, confidence, x0, y0, x1, y1], zero-padded.

    detections: one camera's, as the perception reports them; sign classes come first, then the
    rest, each in descending confidence (a stable sort keeps the perception's order among ties).
    """
    ordered = sorted(detections, key=lambda d: (class_id(d.class_name) == OTHER_CLASS_ID, -d.confidence))
    rows = np.zeros((MAX_DETECTIONS, 6), np.float32)
    for row, det in zip(rows, ordered[:MAX_DETECTIONS]):
        x0, y0, x1, y1 = det.box_xyxy_px
        row[:] = (class_id(det.class_name), min(max(det.confidence, 0.0), 1.0),
                  min(max(x0, 0.0), width_px), min(max(y0, 0.0), height_px),
                  min(max(x1, 0.0), width_px), min(max(y1, 0.0), height_px))
    return rows
