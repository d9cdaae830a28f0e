"""Detection metrics against hand-worked cases."""

import numpy as np
import pytest

from avsim.perception.evaluation import average_precision, iou_xyxy


def test_iou_of_identical_disjoint_and_half_overlapping_boxes():
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [20, 20, 30, 30], [5, 0, 15, 10]], float)
    assert iou_xyxy(a, b)[0] == pytest.approx([1.0, 0.0, 50 / 150])


def test_ap_is_one_for_perfect_ranking_and_lower_when_a_false_positive_ranks_first():
    assert average_precision([0.9, 0.8], [True, True], 2) == pytest.approx(1.0)
    # FP first: precision at recall 0.5 is 1/2, at recall 1 is 2/3 -> AP = 0.5*2/3 + 0.5*2/3.
    assert average_precision([0.9, 0.8, 0.7], [False, True, True], 2) == pytest.approx(2 / 3)


def test_ap_counts_missed_ground_truth():
    assert average_precision([0.9], [True], 4) == pytest.approx(0.25)
    assert np.isnan(average_precision([], [], 0))
