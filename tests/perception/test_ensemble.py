"""The ensemble perception: both networks on one frame, every detection tagged with its network,
and its OR and AND fusion (on hand-made detections; the networks themselves in the closed loop)."""

import numpy as np
import pytest

from avsim.config import PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.base import Detection
from avsim.perception.ensemble import EnsembleDetector, centres_inside_each_other, fuse_and, fuse_votes
from avsim.perception.factory import networks_per_frame

IMAGE = np.zeros((48, 64, 3), np.uint8)


def box(x0, y0, x1, y1, conf=0.8, cls="stop_sign", truncated=False) -> Detection:
    return Detection(cls, conf, (x0, y0, x1, y1), "front", truncated)


class Fixed:
    """A frame detector that reports fixed detections and remembers what it was asked."""

    def __init__(self, *detections: Detection) -> None:
        self.detections = list(detections)
        self.calls = []

    def detect(self, image_rgb, camera, *, region_px=None):
        self.calls.append((image_rgb, camera, region_px))
        return list(self.detections)


def test_boxes_frame_one_object_when_each_centre_lies_inside_the_other():
    assert centres_inside_each_other(box(10, 10, 30, 30), box(12, 11, 33, 31))
    assert not centres_inside_each_other(box(10, 10, 30, 30), box(25, 25, 45, 45))
    assert not centres_inside_each_other(box(0, 0, 100, 100), box(10, 10, 20, 20))  # a big box swallowing a small one


def test_or_reports_both_networks_tagged_most_confident_first():
    own, coco = Fixed(box(10, 10, 30, 30, 0.6)), Fixed(box(40, 5, 60, 25, 0.7), box(0, 0, 5, 5, 0.2, cls="car"))
    found = EnsembleDetector({"detector": own, "coco": coco}, "or").detect(IMAGE, "front", region_px=(1, 2, 3, 4))
    assert [(d.source, d.confidence) for d in found] == [("coco", 0.7), ("detector", 0.6), ("coco", 0.2)]
    # Both networks saw the same frame and region.
    assert own.calls[0][0] is coco.calls[0][0] is IMAGE and own.calls[0][2] == coco.calls[0][2] == (1, 2, 3, 4)


def test_and_reports_a_stop_sign_only_where_both_see_it_at_the_lower_confidence_with_the_own_box():
    own = Fixed(box(10, 10, 30, 30, 0.9), box(40, 5, 60, 25, 0.95), box(0, 40, 8, 48, 0.7, cls="yield"))
    coco = Fixed(box(11, 9, 31, 31, 0.55), box(12, 10, 29, 30, 0.4), box(100, 100, 120, 120, 0.99))
    found = EnsembleDetector({"detector": own, "coco": coco}, "and").detect(IMAGE, "front")
    stops = [d for d in found if d.class_name == "stop_sign"]
    assert len(stops) == 1  # the 0.95 box has no COCO partner; COCO's 0.99 box no own one
    assert stops[0].box_xyxy_px == (10, 10, 30, 30) and stops[0].confidence == 0.55  # its best partner
    assert stops[0].source == "detector+coco"
    assert [d.class_name for d in found if d.class_name != "stop_sign"] == ["yield"]  # other classes pass as reported


def test_and_keeps_a_truncated_flag_from_either_network():
    fused = fuse_and({"detector": [box(10, 10, 30, 30)], "coco": [box(11, 10, 30, 31, truncated=True)]})
    assert fused[0].truncated


def test_the_ensemble_is_the_own_detector_and_coco_by_default_and_runs_one_network_a_member():
    assert PerceptionConfig().ensemble_members == ("detector", "coco")
    assert networks_per_frame(PerceptionConfig(kind="ensemble")) == 2
    assert networks_per_frame(PerceptionConfig(kind="ensemble", ensemble_members=("detector", "coco", "yolo"))) == 3
    assert networks_per_frame(PerceptionConfig(kind="detector")) == 1
    assert networks_per_frame(PerceptionConfig(kind="oracle")) == 0
    with pytest.raises(ConfigError, match="ensemble_fusion"):
        PerceptionConfig(kind="ensemble", ensemble_fusion="xor")


def test_k_of_n_reports_an_object_once_when_enough_members_see_it():
    per_source = {"detector": [box(10, 10, 30, 30, 0.9)],
                  "coco": [box(11, 9, 31, 31, 0.6), box(50, 50, 70, 70, 0.8)],
                  "yolo": [box(12, 11, 29, 30, 0.7), box(51, 49, 71, 69, 0.5), box(90, 0, 99, 9, 0.95)]}
    two = fuse_votes(per_source, 2)  # each object at its second vote's confidence
    assert [(d.source, d.confidence, d.box_xyxy_px) for d in two] == [
        ("detector+coco+yolo", 0.7, (10, 10, 30, 30)), ("coco+yolo", 0.5, (50, 50, 70, 70))]
    assert [(d.source, d.confidence) for d in fuse_votes(per_source, 3)] == [("detector+coco+yolo", 0.6)]
    one = fuse_votes(per_source, 1)  # every object once, however many members saw it, at its best
    assert sorted((d.source, d.confidence) for d in one) == [
        ("coco+yolo", 0.8), ("detector+coco+yolo", 0.9), ("yolo", 0.95)]
    assert fuse_and(per_source) == fuse_votes(per_source, 3)


def test_two_of_three_is_not_vetoed_by_a_third_members_weak_box():
    per_source = {"detector": [box(10, 10, 30, 30, 0.9)], "coco": [box(11, 9, 31, 31, 0.85)],
                  "yolo": [box(14, 14, 26, 26, 0.15)]}  # YOLOv3-tiny's small box on the legend
    assert [(d.source, d.confidence) for d in fuse_votes(per_source, 2)] == [("detector+coco+yolo", 0.85)]
    assert [d.confidence for d in fuse_votes(per_source, 3)] == [0.15]


def test_k_of_n_through_the_detector_and_its_config_checks():
    members = {"detector": Fixed(box(10, 10, 30, 30, 0.9)), "coco": Fixed(), "yolo": Fixed(box(11, 10, 31, 30, 0.7))}
    found = EnsembleDetector(members, "k_of_n", 2).detect(IMAGE, "front")
    assert [(d.source, d.confidence) for d in found] == [("detector+yolo", 0.7)]
    assert EnsembleDetector(members, "and").detect(IMAGE, "front") == []
    with pytest.raises(ValueError, match="votes"):
        EnsembleDetector(members, "k_of_n", 4)
    with pytest.raises(ConfigError, match="ensemble_k must be in \\[1, 2\\]"):
        PerceptionConfig(kind="ensemble", ensemble_fusion="k_of_n", ensemble_k=3)
    with pytest.raises(ConfigError, match="ensemble_members must be two or more"):
        PerceptionConfig(kind="ensemble", ensemble_members=("coco", "coco"))
    with pytest.raises(ConfigError, match="ensemble_members must be two or more"):
        PerceptionConfig(kind="ensemble", ensemble_members=("detector", "onnx"))
