"""Detection scoring primitives against hand-worked cases."""

import numpy as np
import pytest

from avsim.perception.ap import average_precision, box_areas, box_intersections, box_iou, match_detections, mean_ap


def test_iou_of_identical_disjoint_and_half_overlapping_boxes():
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [20, 20, 30, 30], [5, 0, 15, 10]], float)
    assert box_iou(a, b)[0] == pytest.approx([1.0, 0.0, 50 / 150])


def test_intersections_and_areas_of_boxes():
    a = np.array([[0.0, 0.0, 4.0, 2.0]])
    b = np.array([[2.0, 1.0, 6.0, 5.0], [4.0, 0.0, 8.0, 2.0]])
    assert box_intersections(a, b).tolist() == [[2.0, 0.0]]  # 2 x 1 with the first; the second only touches
    assert box_areas(b).tolist() == [16.0, 8.0]


def test_ap_is_one_for_perfect_ranking_and_lower_when_a_false_positive_ranks_first():
    assert average_precision([0.9, 0.8], [True, True], 2) == pytest.approx(1.0)
    # FP first: precision at recall 0.5 is 1/2, at recall 1 is 2/3 -> AP = 0.5*2/3 + 0.5*2/3.
    assert average_precision([0.9, 0.8, 0.7], [False, True, True], 2) == pytest.approx(2 / 3)


def test_ap_counts_missed_ground_truth():
    assert average_precision([0.9], [True], 4) == pytest.approx(0.25)
    assert np.isnan(average_precision([], [], 0))


def test_matching_is_greedy_by_score_and_each_ground_truth_matches_once():
    gt = np.array([[0, 0, 10, 10]], float)
    dets = np.array([[0, 0, 10, 10], [1, 0, 11, 10]], float)
    # The higher-scored duplicate takes the ground truth; the other is a false positive.
    assert match_detections(dets, np.array([0.4, 0.9]), gt).tolist() == [False, True]
    assert match_detections(dets[:1], np.array([0.9]), gt[:0]).tolist() == [False]


def test_mean_ap_skips_classes_without_ground_truth():
    assert mean_ap({"a": 0.5, "b": float("nan"), "c": 1.0}) == pytest.approx(0.75)
