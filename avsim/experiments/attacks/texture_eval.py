"""`avsim attack eval`: how each texture fares in real MuJoCo renders (not the EOT proxy).

For the clean sign and each attacked texture, with the shipped detector on full 640x480
frames of the front and the side camera:
- the stop-sign confidence at fixed bumper-to-sign distances, per placement;
- a drive-by from `DRIVE_BY_FAR_M` to `DRIVE_BY_NEAR_M`: the fraction of frames, among those
  in which the sign is in view and in range (by the oracle's segmentation), where the
  detector reports it at or above the baseline threshold, and the first-detection distance;
- a Fig. 3-like grid of the front camera at 30 m with the detector's box and score drawn.

A detection counts for the sign only if its box overlaps the sign's ground-truth box
(IoU >= 0.3), so a false positive elsewhere never props up an attacked sign's score.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.outputs import write_image
from avsim.perception.ap import box_iou
from avsim.perception.base import Detection
from avsim.perception.factory import build_perception
from avsim.vehicle.physics import FRONT_BUMPER_X_M

FIXED_DISTANCES_M = (10.0, 20.0, 30.0, 40.0, 50.0)
# The drive-by starts beyond the detector's range (its clean recall falls below 0.5 at 100 m)
# so that the curves show where each sign is first seen.
DRIVE_BY_FAR_M, DRIVE_BY_NEAR_M, DRIVE_BY_STEP_M = 140.0, 4.0, 1.0
MATCH_IOU = 0.3
CAMERAS = ("front", "side")


def display_name(sign: str) -> str:
    """'clean', a texture name, or a PNG path's file stem."""
    return Path(sign).stem if sign.lower().endswith(".png") else sign


@dataclass
class TextureReport:
    """One texture in one town, per placement and camera. Distances: front bumper to sign [m]."""

    sign: str
    conf_at_m: dict[str, dict[str, dict[float, float]]] = field(default_factory=dict)  # camera -> placement -> dist -> conf
    detection_rate: dict[str, dict[str, float]] = field(default_factory=dict)  # camera -> placement -> rate
    first_detection_m: dict[str, dict[str, float | None]] = field(default_factory=dict)
    drive_by: dict[str, dict[str, list[tuple[float, float]]]] = field(default_factory=dict)  # (dist, conf) pairs

    def mean_conf(self, camera: str = "front") -> float:
        """Mean stop-sign confidence of `camera` over every placement and fixed distance (NaNs skipped)."""
        values = [c for per_dist in self.conf_at_m[camera].values() for c in per_dist.values()]
        return float(np.nanmean(values))


def sign_detection(found: list[Detection], truth: Detection) -> Detection | None:
    """The most confident of `found` whose box overlaps the true sign's (IoU >= MATCH_IOU); None
    if none does. A detection elsewhere (a tree scored as a stop sign) never stands for the sign."""
    ious = box_iou(np.array([d.box_xyxy_px for d in found]).reshape(-1, 4), np.array([truth.box_xyxy_px]))[:, 0]
    matched = [d for d, iou in zip(found, ious) if iou >= MATCH_IOU]
    return max(matched, key=lambda d: d.confidence) if matched else None


def _sign_confidence(loop: ClosedLoop, oracle, camera: str) -> tuple[float | None, float, float]:
    """(confidence of the best detection matching the stop sign, or 0; its box height [px];
    the true box height [px]). The confidence is None when the sign is not in the camera's view."""
    truth = [d for d in oracle.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
    if not truth:
        return None, 0.0, 0.0
    true_height_px = truth[0].height_px
    found = [d for d in loop.perception.detect(loop.rig, loop.data, camera) if d.class_name == "stop_sign"]
    best = sign_detection(found, truth[0])
    if best is None:
        return 0.0, 0.0, true_height_px
    return best.confidence, best.height_px, true_height_px


def _place(loop: ClosedLoop, bumper_to_sign_m: float) -> None:
    bumper_x = loop.scene.stop_sign.base_pos_m[0] - bumper_to_sign_m
    loop.vehicle.place(bumper_x - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)


def evaluate_texture(sign: str, town: str, placements: tuple[str, ...], threshold: float,
                     base: SimConfig | None = None, detector: str = "detector") -> TextureReport:
    """Measure one texture (a `--sign` value) in `town` at each placement, with the perception
    `detector` (detector, coco or yolo).

    Confidences are the detector's at any box size; the detection rate and the first
    detection count a frame as the car's pipeline does: confidence >= `threshold` and a box
    at least `perception.min_box_height_px` tall.
    """
    base = base or SimConfig()
    min_height_px = base.perception.min_box_height_px
    report = TextureReport(sign)
    for camera in CAMERAS:
        for table in (report.conf_at_m, report.detection_rate, report.first_detection_m, report.drive_by):
            table[camera] = {}
    for placement in placements:
        config = with_overrides(base, {"scenario": {"town": town, "placement": placement, "sign": sign},
                                       "perception": {"kind": detector, "min_confidence": 0.05, "min_box_height_px": 1}})
        loop = ClosedLoop(config)
        try:
            oracle = build_perception(PerceptionConfig(kind="oracle", oracle_min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
            fixed = {camera: {} for camera in CAMERAS}
            for dist_m in FIXED_DISTANCES_M:
                _place(loop, dist_m)
                for camera in CAMERAS:
                    conf, _, _ = _sign_confidence(loop, oracle, camera)
                    fixed[camera][dist_m] = conf if conf is not None else float("nan")
            sequence = {camera: [] for camera in CAMERAS}
            for dist_m in np.arange(DRIVE_BY_FAR_M, DRIVE_BY_NEAR_M - 1e-9, -DRIVE_BY_STEP_M):
                _place(loop, float(dist_m))
                for camera in CAMERAS:
                    conf, height_px, true_height_px = _sign_confidence(loop, oracle, camera)
                    if conf is not None:
                        sequence[camera].append((float(dist_m), conf, height_px, true_height_px))
        finally:
            loop.close()
        for camera in CAMERAS:
            report.conf_at_m[camera][placement] = fixed[camera]
            seen = sequence[camera]
            hits = [d for d, c, h, _ in seen if c >= threshold and h >= min_height_px]
            # The rate counts frames in range: the sign is in view and tall enough to be reported.
            in_range = [d for d, _, _, true_h in seen if true_h >= min_height_px]
            report.detection_rate[camera][placement] = len(set(hits) & set(in_range)) / len(in_range) if in_range else float("nan")
            report.first_detection_m[camera][placement] = max(hits) if hits else None
            report.drive_by[camera][placement] = [(d, c) for d, c, _, _ in seen]
    return report


def fig3_grid(signs: list[str], out_path: Path, town: str = "town07", placement: str = "standard",
              dist_m: float = 30.0, base: SimConfig | None = None, detector: str = "detector") -> Path:
    """A grid of the front camera's view of each texture at `dist_m`, cropped around the sign,
    with the detector's stop-sign box and score drawn (like the study's Fig. 3)."""
    tiles = []
    for sign in signs:
        config = with_overrides(base or SimConfig(), {"scenario": {"town": town, "placement": placement, "sign": sign},
                                                      "perception": {"kind": detector, "min_confidence": 0.05,
                                                                     "min_box_height_px": 1}})
        loop = ClosedLoop(config)
        try:
            _place(loop, dist_m)
            image = loop.rig.render_rgb(loop.data, "front")[..., ::-1].copy()
            oracle = build_perception(PerceptionConfig(kind="oracle", oracle_min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
            truth = [d for d in oracle.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"][0]
            found = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
        finally:
            loop.close()
        best = sign_detection(found, truth)
        cx, cy = (truth.box_xyxy_px[0] + truth.box_xyxy_px[2]) / 2, (truth.box_xyxy_px[1] + truth.box_xyxy_px[3]) / 2
        half = 40
        x0 = int(np.clip(cx - half, 0, image.shape[1] - 2 * half))
        y0 = int(np.clip(cy - half, 0, image.shape[0] - 2 * half))
        crop = image[y0:y0 + 2 * half, x0:x0 + 2 * half]
        tile = cv2.resize(crop, (320, 320), interpolation=cv2.INTER_NEAREST)
        scale = 320 / (2 * half)
        label = "no detection"
        if best is not None:
            bx0, by0, bx1, by1 = ((v - o) * scale for v, o in zip(best.box_xyxy_px, (x0, y0, x0, y0)))
            cv2.rectangle(tile, (int(bx0), int(by0)), (int(bx1), int(by1)), (0, 255, 0), 2)
            label = f"stop_sign {best.confidence:.2f}"
        cv2.rectangle(tile, (0, 0), (320, 44), (0, 0, 0), -1)
        cv2.putText(tile, display_name(sign), (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
        cv2.putText(tile, label, (8, 38), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 255, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    while len(tiles) % 3:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[i:i + 3]) for i in range(0, len(tiles), 3)]
    return write_image(out_path, np.vstack(rows))
