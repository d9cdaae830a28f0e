"""One frame, one network: what the benchmark keeps of its stop-sign detections.

Each network looks at the camera's deployed region of interest (avsim/sensors/regions.py, which
follows camera.preset) with its default input and precision, as in the closed loop, with no range limit.
At the threshold (the braking threshold, 0.5):
- **found**: a `stop_sign` detection matches the labelled stop sign with IoU >= 0.5 (greedy, as AP);
- **found_centred**: one is centred inside the labelled box (YOLOv3-tiny often boxes only the legend);
- **false stop signs**: detections centred on no labelled stop sign, each with the geom it sits on
  (the most common geom in the middle ninth of its box, from a segmentation render; "sky" where no
  geom is), named without the numbers of repeated props ("tree_right/crown", "bldg_left/roof"), and
  how much of a labelled stop sign its box covers (0: apart from every sign; above 0: a box displaced
  from the sign onto what stands beside it, which still ranges the sign wrongly).
Every stop-sign detection at or above min_confidence, with whether it matches (IoU >= 0.5), is kept
for the stop sign's AP over the whole set.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np

from avsim.config import PerceptionConfig
from avsim.perception.ap import box_areas, box_intersections, match_detections
from avsim.realism.frame_set import Frame
from avsim.sensors.camera import CameraRig
from avsim.sensors.regions import deployed_region_px

_COPY_NUMBER = re.compile(r"_?-?\d+")

# A false stop sign's row: score, x0, y0, x1, y1 [px], the geom it sits on, the fraction of a labelled
# stop sign its box covers (`sign_cover`). The positions of the last two:
FALSE_ON, FALSE_SIGN_COVER = 5, 6


def build_networks(names: tuple[str, ...]) -> dict[str, object]:
    """The frame detectors by name, each at its config's defaults (one torch thread)."""
    import torch

    from avsim.perception.factory import build_frame_detector

    torch.set_num_threads(1)
    return {name: build_frame_detector(PerceptionConfig(kind=name)) for name in names}


def geom_label(model: mujoco.MjModel, geom_id: int) -> str:
    """A geom's kind: its name without copy numbers, its body's where it has none; "sky" for -1."""
    if geom_id < 0:
        return "sky"
    name = model.geom(geom_id).name or model.body(int(model.geom_bodyid[geom_id])).name
    return _COPY_NUMBER.sub("", name)


def geom_under_box(model: mujoco.MjModel, ids: np.ndarray, image_height_px: int, box_xyxy_px) -> str:
    """What a box sits on: `geom_label` of the geom most common in the middle ninth of the box.

    ids: (s·H, s·W) geom ids of a segmentation render (`CameraRig.render_segmentation`, -1 where no
    geom is), s its supersampling; image_height_px: H, the RGB image's height, in whose pixels
    box_xyxy_px (x0, y0, x1, y1) is given. "outside" for a box wholly outside the image.
    """
    scale = ids.shape[0] / image_height_px
    x0, y0, x1, y1 = np.asarray(box_xyxy_px, float) * scale
    w, h = x1 - x0, y1 - y0
    middle = ids[int(y0 + h / 3):max(int(y1 - h / 3), int(y0 + h / 3) + 1), int(x0 + w / 3):max(int(x1 - w / 3), int(x0 + w / 3) + 1)]
    values, counts = np.unique(middle, return_counts=True)
    return geom_label(model, int(values[np.argmax(counts)])) if values.size else "outside"


def sign_cover(box_xyxy_px, truth: np.ndarray) -> float:
    """The largest fraction of a labelled sign's area (truth: (N, 4) xyxy [px]) that the box covers;
    0.0 where it touches none."""
    if not len(truth):
        return 0.0
    return float(np.max(box_intersections(box_xyxy_px, truth)[0] / np.maximum(box_areas(truth), 1e-9)))


def _centred(boxes: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(D,) whether each box's centre lies inside any of the (N, 4) truth boxes."""
    if not len(boxes) or not len(truth):
        return np.zeros(len(boxes), bool)
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    return ((centres[:, None] >= truth[None, :, :2]) & (centres[:, None] <= truth[None, :, 2:])).all(-1).any(1)


def score_frame(frame: Frame, detector: object, threshold: float, model: mujoco.MjModel, data: mujoco.MjData,
                rig: CameraRig, segmentation: dict) -> dict:
    """The row of one frame for one network. `segmentation` caches the frame's geom-id image across
    networks (filled on the first false stop sign)."""
    region = deployed_region_px(frame.camera, rig.config)  # as the closed loop searches it
    stops = [d for d in detector.detect(frame.image, frame.camera, region_px=region) if d.class_name == "stop_sign"]
    scores = np.asarray([d.confidence for d in stops], float)
    boxes = np.asarray([d.box_xyxy_px for d in stops], float).reshape(-1, 4)
    truth = frame.stop_boxes
    counted = scores >= threshold
    matched_at_threshold = np.zeros(len(stops), bool)
    matched_at_threshold[counted] = match_detections(boxes[counted], scores[counted], truth)
    false = counted & ~_centred(boxes, truth)
    false_rows = []
    for score, box in zip(scores[false], boxes[false]):
        if "ids" not in segmentation:
            segmentation["ids"] = rig.render_segmentation(data, frame.camera)
        on = geom_under_box(model, segmentation["ids"], frame.image.shape[0], box)
        false_rows.append([round(float(score), 4), *[round(float(v), 1) for v in box], on, round(sign_cover(box, truth), 3)])
    return {
        "found": bool(matched_at_threshold.any()),
        "found_centred": bool((counted & _centred(boxes, truth)).any()),
        "best_score": round(float(scores[matched_at_threshold].max()) if matched_at_threshold.any() else 0.0, 4),
        "false_stop_signs": false_rows,
        # For AP: every stop-sign detection (score, matches a labelled stop sign at IoU >= 0.5).
        "ap_detections": [[round(float(s), 4), bool(t)] for s, t in zip(scores, match_detections(boxes, scores, truth))],
        "n_truth": int(len(truth)),
    }
