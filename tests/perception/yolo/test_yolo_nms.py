"""The torch NMS keeps exactly what OpenCV's greedy NMSBoxesBatched keeps."""

import numpy as np
import pytest
import torch

from avsim.perception.detector.postprocess import nms as opencv_nms
from avsim.perception.yolo.nms import batched_nms, pairwise_iou


@pytest.mark.parametrize("seed", range(20))
def test_same_kept_boxes_as_opencv_greedy_nms(seed):
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 120))
    xy = rng.uniform(0, 100, (count, 2))
    boxes = np.concatenate([xy, xy + rng.uniform(2, 40, (count, 2))], axis=1)
    scores = rng.permutation(count).astype(np.float32) / count + 0.01  # distinct: no tie-break question
    classes = rng.integers(0, 3, count)
    kept = batched_nms(torch.from_numpy(boxes), torch.from_numpy(scores), torch.from_numpy(classes), 0.45)
    assert kept.tolist() == opencv_nms(boxes, scores, classes, 0.45).tolist()


def test_chains_resolve_greedily_and_empty_input_keeps_nothing():
    # a suppresses b, b would suppress c, but b is gone, so c stays
    boxes = torch.tensor([[0.0, 0, 10, 10], [3, 0, 13, 10], [6, 0, 16, 10]])
    assert batched_nms(boxes, torch.tensor([0.9, 0.8, 0.7]), torch.zeros(3, dtype=torch.long), 0.45).tolist() == [0, 2]
    assert batched_nms(torch.zeros(0, 4), torch.zeros(0), torch.zeros(0, dtype=torch.long), 0.5).numel() == 0
    assert torch.allclose(pairwise_iou(boxes)[0, 1], torch.tensor(70 / 130))
