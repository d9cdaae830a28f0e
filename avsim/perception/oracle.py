"""`oracle` perception: ground-truth sign boxes from segmentation rendering.

An explicitly named oracle, not a detector: it reads which pixels belong to which
sign face from MuJoCo's segmentation render and reports every sign whose box is at
least `min_box_height_px` tall (a real detector's range limit), with confidence 1.
"""

from __future__ import annotations

import mujoco

from avsim.perception.base import Detection, Perception, touches_border
from avsim.sensors.camera import CameraRig
from avsim.world.signs import PlacedSign


class OraclePerception(Perception):
    """Ground truth, explicitly named: each sign's visible box from a segmentation render
    (`CameraRig.sign_boxes`, in image pixels), confidence 1, once the box is `min_box_height_px`
    tall (the oracle's range). No network and no pixels of colour: an oracle mode, not a perception."""

    name = "oracle"

    def __init__(self, model: mujoco.MjModel, signs: tuple[PlacedSign, ...], min_box_height_px: float) -> None:
        self._kinds = {sign.name: sign.kind for sign in signs}
        # Face geom and outline corners per sign: the corners bound the pixels read back.
        self._faces = {sign.name: (model.geom(sign.face_geom).id, sign.corners_m()) for sign in signs}
        self._min_box_height_px = min_box_height_px

    def detect(self, rig: CameraRig, data: mujoco.MjData, camera: str) -> list[Detection]:
        """Ground-truth boxes [px] of the signs `camera` sees (from segmentation), confidence 1, those at
        least `min_box_height_px` tall, tallest first: the oracle mode, not a perception.
        """
        # A sign too far for the oracle's range is not rendered at all: most of an approach's frames.
        boxes = rig.sign_boxes(data, camera, self._faces, min_height_px=self._min_box_height_px)
        size = rig.intrinsics(camera)
        detections = [
            Detection(self._kinds[name], 1.0, box, camera, touches_border(box, size.width_px, size.height_px))
            for name, box in boxes.items()
            if box[3] - box[1] >= self._min_box_height_px
        ]
        return sorted(detections, key=lambda d: -d.height_px)
