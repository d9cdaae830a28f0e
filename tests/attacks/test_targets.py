"""The attack targets' fusion of several networks (`avsim.attacks.targets.EnsembleTarget`), on stub members."""

import pytest
import torch

from avsim.attacks.objective import StopEvidence
from avsim.attacks.targets import TARGET_MEMBERS, TARGET_NAMES, TARGET_VOTE_K, EnsembleTarget


class StubTarget:
    """A member whose evidence is fixed per view: score, objectness and class probability all `score`."""

    def __init__(self, scores: list[float], height_px: float) -> None:
        self.scores = torch.tensor(scores)
        self.height_px = height_px

    def evidence(self, images, sign_boxes_px):
        s = self.scores
        return StopEvidence(s, s, s, torch.logit(s), torch.full_like(s, self.height_px))

    def weight_hashes(self):
        return {}


def members():
    # Two views; view 0: the own detector hidden, view 1: only YOLOv3-tiny weak.
    return [StubTarget([0.05, 0.9], 20.0), StubTarget([0.9, 0.85], 20.0), StubTarget([0.6, 0.15], 5.0)]


def test_or_fusion_scores_the_network_that_sees_the_sign_best_and_the_vote_the_second():
    images, boxes = torch.zeros(2, 3, 8, 8), torch.zeros(2, 4)
    any_of = EnsembleTarget(members()).evidence(images, boxes)
    vote = EnsembleTarget(members(), vote_k=2).evidence(images, boxes)
    # Soft, at the ensemble's temperature 0.05: within t log(3) = 0.055 of the hard value, and below it.
    assert torch.allclose(any_of.score, torch.tensor([0.9, 0.9]), atol=0.06) and torch.all(any_of.score <= 0.9)
    assert torch.allclose(vote.score, torch.tensor([0.6, 0.85]), atol=0.06)
    assert float(vote.score[0]) < float(any_of.score[0]) - 0.2  # hiding the sign from one network moves the vote
    assert torch.allclose(vote.class_logit, torch.logit(torch.tensor([0.6, 0.85])))
    # The box height is the members' geometric mean either way: (20 * 20 * 5)^(1/3).
    assert torch.allclose(vote.box_height_px, torch.full((2,), 2000.0 ** (1 / 3)))
    with pytest.raises(ValueError, match="vote_k"):
        EnsembleTarget(members(), vote_k=4)


def test_every_target_name_has_its_members_and_the_vote_target_is_two_of_three():
    assert set(TARGET_NAMES) == set(TARGET_MEMBERS)
    assert TARGET_MEMBERS["ensemble_all_2of3"] == ("detector", "coco", "yolo") and TARGET_VOTE_K["ensemble_all_2of3"] == 2
    assert set(TARGET_VOTE_K) <= {name for name, m in TARGET_MEMBERS.items() if len(m) > 1}
