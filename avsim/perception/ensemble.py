"""`ensemble` perception: several networks on the same frame (a defence).

The members are `perception.ensemble_members`, any of avsim's own detector, the COCO
CenterNet and YOLOv3-tiny (default: the first two). Networks trained apart, on different data (avsim's renders; COCO photographs), rarely share
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
- "k_of_n": a stop sign is reported where at least `perception.ensemble_k` members report one
  on the same object, with the box of the earliest member in the group, the members joined by
  "+", and the k-th highest confidence in the group: then the fused sign clears a policy's
  threshold exactly when k members' own detections do. (The lowest confidence, as "and" takes,
  would let a third member's weak box veto two members that see the sign clearly.) k = 1 is
  one detection per object, at its best member's confidence, instead of OR's one per network;
  k = n is "and".
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from avsim.config import ENSEMBLE_FUSIONS
from avsim.perception.base import Detection
from avsim.perception.frame import FrameDetector, Region

STOP_CLASS = "stop_sign"


def centres_inside_each_other(a: Detection, b: Detection) -> bool:
    """Whether each box's centre lies inside the other box: the two boxes frame one object."""
    def centre_in(box: tuple[float, float, float, float], other: tuple[float, float, float, float]) -> bool:
        cx, cy = (other[0] + other[2]) / 2, (other[1] + other[3]) / 2
        return box[0] <= cx <= box[2] and box[1] <= cy <= box[3]

    return centre_in(a.box_xyxy_px, b.box_xyxy_px) and centre_in(b.box_xyxy_px, a.box_xyxy_px)


def fuse_votes(per_source: Mapping[str, list[Detection]], votes: int) -> list[Detection]:
    """k-of-n fusion (module docstring) of tagged detections, most confident first.

    Each stop sign of each member, in member order, anchors a group: the most confident stop
    sign of every later member on the same object (centres inside each other). A group of at
    least `votes` members is reported once, at its `votes`-th highest confidence (for "and",
    its lowest); its detections anchor nothing more.
    """
    names = list(per_source)
    used: set[tuple[str, int]] = set()
    fused = []
    for position, name in enumerate(names):
        for index, det in enumerate(per_source[name]):
            if det.class_name != STOP_CLASS or (name, index) in used:
                continue
            group = [(name, index, det)]
            for other in names[position + 1:]:
                matches = [(j, d) for j, d in enumerate(per_source[other])
                           if d.class_name == STOP_CLASS and centres_inside_each_other(det, d)]
                if matches:
                    j, best = max(matches, key=lambda item: item[1].confidence)
                    group.append((other, j, best))
            if len(group) < votes:
                continue
            used |= {(member, j) for member, j, _ in group}
            kth_highest = sorted((d.confidence for _, _, d in group), reverse=True)[votes - 1]
            fused.append(dataclasses.replace(
                det, confidence=kth_highest,
                truncated=any(d.truncated for _, _, d in group), source="+".join(member for member, _, _ in group)))
    rest = [d for name in names for d in per_source[name] if d.class_name != STOP_CLASS]
    return sorted(fused + rest, key=lambda d: -d.confidence)


def fuse_and(per_source: Mapping[str, list[Detection]]) -> list[Detection]:
    """AND fusion (module docstring): a stop sign every member reports."""
    return fuse_votes(per_source, len(per_source))


class EnsembleDetector:
    """A frame detector that runs every member on the frame and fuses their detections (a `FrameDetector`).

    members: name -> frame detector, the first giving fused boxes; fusion: "or", "and" or
    "k_of_n" (with `votes`, 1 <= votes <= members).
    """

    def __init__(self, members: Mapping[str, FrameDetector], fusion: str, votes: int | None = None) -> None:
        if fusion not in ENSEMBLE_FUSIONS:
            raise ValueError(f"unknown ensemble fusion {fusion!r}; choose one of: {', '.join(ENSEMBLE_FUSIONS)}")
        self.members = dict(members)
        self.fusion = fusion
        self.votes = {"and": len(self.members), "k_of_n": votes}.get(fusion)
        if fusion == "k_of_n" and not (votes and 1 <= votes <= len(self.members)):
            raise ValueError(f"k_of_n fusion needs 1 <= votes <= {len(self.members)}, got {votes}")

    def detect(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None) -> list[Detection]:
        """Every member's detections in `image_rgb` (H, W, 3) uint8 RGB, each tagged with its source;
        fused by vote when `votes` is set, else all of them, most confident first.
        """
        return self.fuse(self.detect_members(image_rgb, camera, region_px=region_px))

    def detect_members(self, image_rgb: np.ndarray, camera: str, *, region_px: Region | None = None
                       ) -> dict[str, list[Detection]]:
        """Each member's detections in `image_rgb`, tagged with its name, before fusion: what ensembles of
        the same members but another fusion find in the frame too (`avsim.frame_sharing`)."""
        return {name: [dataclasses.replace(d, source=name) for d in member.detect(image_rgb, camera, region_px=region_px)]
                for name, member in self.members.items()}

    def fuse(self, per_source: Mapping[str, list[Detection]]) -> list[Detection]:
        """`detect_members`' detections fused by this ensemble's rule (module docstring), most confident first."""
        if self.votes is not None:
            return fuse_votes(per_source, self.votes)
        return sorted((d for dets in per_source.values() for d in dets), key=lambda d: -d.confidence)
