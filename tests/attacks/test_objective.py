"""The objectives' arithmetic: soft maximum, braking gate, box height, on synthetic maps."""

import math

import pytest
import torch

from avsim.attacks.objective import (BOX_SCORE_TEMPERATURE, driveby_objective, gate_weight, kth_largest_in_windows,
                                     log_height_ratio, soft_kth_largest, soft_maximum, stop_evidence)
from avsim.perception.detector.boxes import cell_centres


@pytest.mark.parametrize("seed", range(5))
def test_soft_maximum_lies_between_the_mean_it_replaces_and_the_maximum(seed):
    values = torch.rand(37, generator=torch.Generator().manual_seed(seed))
    for temperature in (0.01, 0.05, 0.3, 3.0):
        soft = float(soft_maximum(values, temperature))
        assert float(values.mean()) - 1e-6 <= soft <= float(values.max()) + 1e-6
    # Cold, it is the maximum; hot, the mean.
    assert float(soft_maximum(values, 1e-4)) == pytest.approx(float(values.max()), abs=1e-3)
    assert float(soft_maximum(values, 1e4)) == pytest.approx(float(values.mean()), abs=1e-4)


def test_soft_kth_largest_is_what_a_k_of_n_vote_reports_made_smooth():
    # Three networks' scores for two views: the own detector hidden, COCO and YOLOv3-tiny not.
    scores = torch.tensor([[0.05, 0.9, 0.6], [0.9, 0.85, 0.15]])
    cold = soft_kth_largest(scores, 2, 1e-4)
    assert torch.allclose(cold, torch.tensor([0.6, 0.85]), atol=1e-3)  # the second-highest of each view
    assert torch.equal(soft_kth_largest(scores, 1, 0.05), soft_maximum(scores, 0.05))
    assert torch.allclose(soft_kth_largest(scores, 3, 1e-4), scores.amin(dim=-1), atol=1e-3)
    # Warm, it stays between the smallest and the largest score.
    warm = soft_kth_largest(scores, 2, 0.05)
    assert torch.all(warm >= scores.amin(dim=-1)) and torch.all(warm <= scores.amax(dim=-1))
    # Its gradient goes mostly to the second-highest score: lowering the best alone does not pass the vote.
    leaf = scores.clone().requires_grad_(True)
    soft_kth_largest(leaf, 2, 0.05).sum().backward()
    assert int(leaf.grad[0].argmax()) == 2 and int(leaf.grad[1].argmax()) == 1
    with pytest.raises(ValueError, match="k must be in"):
        soft_kth_largest(scores, 4, 0.05)


def test_one_confident_frame_dominates_the_drive_by_objective_but_not_the_mean():
    quiet = torch.full((30,), 0.05)
    one_loud = quiet.clone()
    one_loud[12] = 0.9
    assert float(driveby_objective([one_loud], 0.05)) > 0.6  # the frame that would trigger the brake
    assert float(one_loud.mean()) < 0.1  # a mean objective barely notices it
    assert float(driveby_objective([quiet, one_loud], 0.05)) == pytest.approx(
        (float(soft_maximum(quiet, 0.05)) + float(soft_maximum(one_loud, 0.05))) / 2)


def test_gate_weight_is_the_braking_gate_made_smooth():
    estimate = torch.tensor([20.0, 38.0, 40.0, 42.0, 60.0])
    weight = gate_weight(estimate, 40.0, 1.0)
    assert float(weight[2]) == pytest.approx(0.5)
    assert float(weight[0]) > 0.999 and float(weight[-1]) < 1e-3
    assert torch.all(weight[:-1] >= weight[1:])
    assert torch.equal(gate_weight(estimate, None, 1.0), torch.ones(5))


def test_a_box_20_percent_short_reads_25_percent_far():
    ratio = log_height_ratio(torch.tensor([8.0]), torch.tensor([10.0]))
    assert float(ratio) == pytest.approx(math.log(0.8))
    assert 1 / math.exp(float(ratio)) == pytest.approx(1.25)


def _maps(height: int, width: int, stride: int, sign_cell: tuple[int, int], score_logit: float, log_h: float) -> torch.Tensor:
    """One stride's raw map (1, 1 + 3 + 4, H, W): background everywhere, a sign at one cell."""
    maps = torch.full((1, 8, height, width), -8.0)
    maps[:, 4:] = 0.0
    row, col = sign_cell
    maps[0, 0, row, col] = score_logit  # objectness
    maps[0, 1, row, col] = score_logit  # stop-sign class
    maps[0, 7, row, col] = log_h
    return maps


def test_stop_evidence_reads_the_score_and_the_box_height_of_the_sign_cells():
    stride = 8
    maps = _maps(8, 8, stride, (3, 4), 4.0, math.log(3.0))  # a box 3 strides (24 px) tall
    centre = cell_centres(8, 8, stride)[3 * 8 + 4]
    box = torch.tensor([[centre[0] - 10, centre[1] - 12, centre[0] + 10, centre[1] + 12]])
    evidence = stop_evidence([maps], (stride,), box)
    assert float(evidence.score) == pytest.approx(torch.sigmoid(torch.tensor(4.0)).item() ** 2, rel=1e-5)
    assert float(evidence.box_height_px) == pytest.approx(24.0, rel=1e-3)
    # A box elsewhere sees no sign cell: no score, no height.
    far = torch.tensor([[0.0, 0.0, 4.0, 4.0]])
    away = stop_evidence([maps], (stride,), far)
    assert float(away.score) < 1e-6 and float(away.box_height_px) < 25.0


def test_the_reported_height_follows_the_best_scored_cell():
    stride = 8
    maps = _maps(8, 8, stride, (3, 4), 4.0, math.log(3.0))
    maps[0, 0, 3, 5] = maps[0, 1, 3, 5] = 1.0  # a neighbour, less sure, with a taller box
    maps[0, 7, 3, 5] = math.log(5.0)
    centre = cell_centres(8, 8, stride)[3 * 8 + 4]
    box = torch.tensor([[centre[0] - 14, centre[1] - 12, centre[0] + 14, centre[1] + 12]])
    height = float(stop_evidence([maps], (stride,), box).box_height_px)
    # Scores 0.964 against 0.534: softmax(score / 0.05) gives the neighbour e^-8.6 of the weight.
    assert 24.0 <= height < 24.0 + 16.0 * math.exp(-(0.964 - 0.534) / BOX_SCORE_TEMPERATURE) * 2


def test_the_kth_largest_in_windows_of_a_k_of_n_vote():
    values = torch.tensor([0.1, 0.9, 0.2, 0.8, 0.7, 0.0, 0.3])
    # Windows of 5: [.1 .9 .2 .8 .7], [.9 .2 .8 .7 0], [.2 .8 .7 0 .3]; their 3rd largest values.
    assert torch.allclose(kth_largest_in_windows(values, 3, 5), torch.tensor([0.7, 0.7, 0.3]))
    assert torch.equal(kth_largest_in_windows(values, 1, 1), values)
    assert torch.allclose(kth_largest_in_windows(values[:3], 3, 5), torch.tensor([0.1]))  # shorter than a window
    with pytest.raises(ValueError, match="k-of-n"):
        kth_largest_in_windows(values, 4, 3)
