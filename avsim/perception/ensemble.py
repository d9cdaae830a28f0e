"""`ensemble` perception: avsim's own detector and the COCO CenterNet on the same frame (a defence).

Two networks trained apart, on different data (avsim's renders; COCO photographs), rarely share
an adversarial blind spot: a texture optimised against one transfers poorly to the other (the
study's five textures did not transfer to the COCO network at all). Detector ensembles as a
defence: Liu et al. 2018 ("Towards robust neural networks via random self-ensemble") and, for
detectors, the multi-model fusion Armory and the physical-attack literature evaluate; their
known weakness is an attacker who optimises against every member at once (issue 14's
`--detector ensemble` target). Assumption: the members' errors are independent.

Each camera frame is rendered once, with one draw of sensor noise, and every member runs on
it; each detection is tagged with its network (`Detection.source`). Fusion
(`perception.ensemble_fusion`):
- "or": every member's detections are reported. A policy that brakes on the most confident
  stop sign then brakes when either network sees it: more recall, and the union of both
  networks' false alarms.
- "and": a stop sign is reported only where every member reports one on the same object:
  boxes whose centres lie inside each other. The pair becomes one detection with the first
  member's box (avsim's detector, whose boxes give the policies their range), the lower of
  the confidences and source "detector+coco". Fewer false alarms, and the recall of the
  weaker network. The other classes, which no policy acts on, are reported as each network
  reports them (COCO has no yield or speed-limit class).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from avsim.config import ENSEMBLE_FUSIONS
from avsim.perception.base import Detection
from avsim.perception.frame import FrameDetector, Region

# The member networks, by their FRAME_DETECTORS names, the first giving fused boxes.
ENSEMBLE_MEMBERS = ("detector", "coco")
STOP_CLASS = "stop_sign"


def centres_inside_each_other(a: Detection, b: Detection) -> bool:
    """Whether each box's centre lies inside the other box: the two boxes frame one object."""
    def centre_in(box: tuple[float, float, float, float], other: tuple[float, float, float, float]) -> bool:
        cx, cy = (other[0] + other[2]) / 2, (other[1] + other[3]) / 2
        return box[0] <= cx <= box[2] and box[1] <= cy <= box[3]

    return centre_in(a.box_xyxy_px, b.box_xyxy_px) and centre_in(b.box_xyxy_px, a.box_xyxy_px)


def fuse_and(per_source: Mapping[str, list[Detection]]) -> list[Detection]:
    """AND fusion (module docstring) of tagged detections, member by member, most confident first."""
    names = list(per_source)
    first, others = names[0], names[1:]
    fused = []
    for det in per_source[first]:
        if det.class_name != STOP_CLASS:
            continue
        partners = []
        for name in others:
            matches = [d for d in per_source[name] if d.class_name == STOP_CLASS and centres_inside_each_other(det, d)]
            if not matches:
                break
            partners.append(max(matches, key=lambda d: d.confidence))
        else:
            fused.append(dataclasses.replace(
                det, confidence=min(det.confidence, *(p.confidence for p in partners)),
                truncated=det.truncated or any(p.truncated for p in partners), source="+".join(names)))
    rest = [d for name in names for d in per_source[name] if d.class_name != STOP_CLASS]
    return sorted(fused + rest, key=lambda d: -d.confidence)


class EnsembleDetector:
    """A frame detector that runs every member on the frame and fuses their detections (a `FrameDetector`).

    members: name -> frame detector, in ENSEMBLE_MEMBERS order; fusion: "or" or "and".
    """

    def __init__(self, members: Mapping[str, FrameDetector], fusion: str) -> None:
        if fusion not in ENSEMBLE_FUSIONS:
            raise ValueError(f"unknown ensemble fusion {fusion!r}; choose one of: {', '.join(ENSEMBLE_FUSIONS)}")
        self.members = dict(members)
        self.fusion = fusion

    def detect(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None) -> list[Detection]:
        per_source = {name: [dataclasses.replace(d, source=name) for d in member.detect(image_rgb, camera, region_px=region_px)]
                      for name, member in self.members.items()}
        if self.fusion == "and":
            return fuse_and(per_source)
        return sorted((d for dets in per_source.values() for d in dets), key=lambda d: -d.confidence)
