"""NMS semantics (OpenCV, class-aware) and decoding of hand-set network outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from avsim.perception.detector.boxes import decode_boxes, encode_boxes
from avsim.perception.detector.postprocess import decode, nms


def test_nms_keeps_higher_score_of_overlapping_same_class_boxes():
    boxes = np.array([[10, 10, 50, 50], [12, 12, 52, 52]], float)
    keep = nms(boxes, np.array([0.6, 0.9]), np.array([0, 0]), iou_threshold=0.5)
    assert keep.tolist() == [1]


def test_nms_does_not_suppress_across_classes():
    boxes = np.array([[10, 10, 50, 50], [12, 12, 52, 52]], float)
    keep = nms(boxes, np.array([0.6, 0.9]), np.array([0, 2]), iou_threshold=0.5)
    assert keep.tolist() == [1, 0]


def test_nms_keeps_both_below_iou_threshold():
    boxes = np.array([[0, 0, 10, 10], [0, 0, 10, 20]], float)  # IoU 0.5
    assert sorted(nms(boxes, np.array([0.9, 0.8]), np.array([1, 1]), iou_threshold=0.55).tolist()) == [0, 1]
    assert nms(boxes, np.array([0.9, 0.8]), np.array([1, 1]), iou_threshold=0.45).tolist() == [0]


def test_nms_handles_sub_pixel_boxes_and_empty_input():
    boxes = np.array([[0.0, 0.0, 1.5, 1.0], [0.0, 0.0, 1.0, 1.0]])  # IoU 2/3 as floats, 1 if rounded
    assert sorted(nms(boxes, np.array([0.9, 0.8]), np.array([0, 0]), iou_threshold=0.7).tolist()) == [0, 1]
    assert nms(np.zeros((0, 4)), np.zeros(0), np.zeros(0), 0.5).shape == (0,)


def _logit(p: float) -> float:
    return math.log(p / (1 - p))


def test_decode_one_confident_cell():
    h_in, w_in = 96, 128
    outputs = [torch.full((1, 8, h_in // s, w_in // s), -10.0) for s in (8, 16)]
    # stride-8 cell (row 5, column 7): centre (60, 44); box centre (62, 42), 24 x 16 px
    row, col, s = 5, 7, 8
    outputs[0][0, 0, row, col] = _logit(0.9)
    outputs[0][0, 1 + 2, row, col] = _logit(0.8)  # speed_limit
    outputs[0][0, 4:, row, col] = torch.tensor([2 / s, -2 / s, math.log(24 / s), math.log(16 / s)])
    det = decode(outputs, conf_threshold=0.5)
    assert len(det) == 1 and det[0].shape == (1, 6)
    torch.testing.assert_close(det[0][0, :4], torch.tensor([50.0, 34.0, 74.0, 50.0]), atol=1e-4, rtol=0)
    assert det[0][0, 4].item() == pytest.approx(0.72, abs=1e-5)
    assert det[0][0, 5].item() == 2
    assert decode(outputs, conf_threshold=0.75)[0].shape == (0, 6)


def test_encode_inverts_decode():
    centres = torch.tensor([[4.0, 4.0], [24.0, 40.0]])
    strides = torch.tensor([8.0, 16.0])
    boxes = torch.tensor([[1.2, 0.5, 13.7, 16.1], [0.0, 10.0, 64.0, 80.0]])
    torch.testing.assert_close(decode_boxes(encode_boxes(boxes, centres, strides), centres, strides), boxes, atol=1e-5, rtol=0)
