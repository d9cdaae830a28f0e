"""`driveby`: hide the sign in every frame of an approach, until it is too late to stop.

Paper: the expectation over transformation of A. Athalye, L. Engstrom, A. Ilyas, K. Kwok,
"Synthesizing Robust Adversarial Examples", ICML 2018, over whole approach sequences, as the
hiding attacks of Y. Zhao, H. Zhu, R. Liang, Q. Shen, S. Zhang, K. Chen, "Seeing isn't
Believing: Towards More Robust Adversarial Attack Against Real World Object Detectors", CCS
2019, optimise one texture over the distances and angles of a drive; the objective is shaped
to avsim's braking policies (issue 14).
Objective: the car brakes on the *first* confident frame inside its braking gate, so the
attack minimises, per sampled drive-by (every frame at the loop's frame spacing from beyond
the gate down to where the sign leaves the view), a soft maximum over the frames
(`objective.soft_maximum`, temperature `temperature`) of
- `objective = "score"`: the stop-sign score, or
- `objective = "gate"`: the score times the smooth braking gate evaluated at the pinhole
  estimate of the *predicted* box (`objective.gate_weight`), so a frame may also be won by
  reading the sign farther than `trigger_dist_m` (range inflation);
plus `range_weight` times the mean log ratio of the predicted to the true box height. Against
the `temporal_vote` defence (`vote_k` of the last `vote_n` frames must see the sign), the soft
maximum runs over each window's `vote_k`-th largest frame value instead
(`objective.kth_largest_in_windows`): the attack need only keep the sign hidden in enough
frames of every window, not in all of them. A step
samples `sequences_per_step` drive-bys (at most `views_per_step` frames each, evenly from a
random phase) and back-propagates through the `grad_frames` frames of highest value in each.
Constraint: the camouflage budget, SSIM >= `ssim_floor` on the sign face, projected after
every step by scaling the change back towards the clean sign, and |delta| <= eps.
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene, optimise_within_ssim
from avsim.attacks.objective import (StopEvidence, driveby_objective, gate_weight, kth_largest_in_windows,
                                     log_height_ratio)

OBJECTIVES = ("score", "gate")


class DriveBy(Attack):
    """Hide the sign over whole approaches (EOT over drive-bys, after Athalye et al. 2018 and Zhao
    et al. 2019): within SSIM >= `ssim_floor` on the face and |delta| <= eps, minimising a soft
    maximum over each drive-by's frames of the stop-sign score (`objective = "score"`) or of the
    score inside the braking gate at `trigger_dist_m` [m] (`"gate"`), optionally per `vote_k` of
    `vote_n` windows. Call it on a clean texture (3, H, W) in [0, 1].
    """

    name = "driveby"
    paper = "Athalye et al. 2018 (EOT) and Zhao et al. 2019 (hiding over a drive)"

    def __init__(self, scene: Scene, *, ssim_floor: float = 0.7, eps: float = 0.5, objective: str = "gate",
                 temperature: float = 0.05, trigger_dist_m: float = 40.0, gate_softness_m: float = 2.0,
                 range_weight: float = 0.0, sequences_per_step: int = 1, grad_frames: int = 8, steps: int = 300,
                 views_per_step: int = 40, lr: float = 0.01, vote_k: int = 1, vote_n: int = 1, seed: int = 0) -> None:
        if objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
        if not 0 < ssim_floor < 1 or not 0 < eps <= 1 or temperature <= 0 or gate_softness_m <= 0 or sequences_per_step < 1 \
                or grad_frames < 1 or not 1 <= vote_k <= vote_n:
            raise ValueError("need 0 < ssim_floor < 1, 0 < eps <= 1, temperature > 0, gate_softness_m > 0, "
                             "sequences_per_step, grad_frames >= 1 and 1 <= vote_k <= vote_n")
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, ssim_floor=ssim_floor,
                         eps=eps, objective=objective, temperature=temperature, trigger_dist_m=trigger_dist_m,
                         gate_softness_m=gate_softness_m, range_weight=range_weight,
                         sequences_per_step=sequences_per_step, grad_frames=grad_frames,
                         **({"vote_k": vote_k, "vote_n": vote_n} if vote_n > 1 else {}))
        self.ssim_floor, self.eps, self.objective, self.temperature = ssim_floor, eps, objective, temperature
        self.trigger_dist_m, self.gate_softness_m, self.range_weight = trigger_dist_m, gate_softness_m, range_weight
        self.sequences_per_step, self.grad_frames = sequences_per_step, grad_frames
        self.vote_k, self.vote_n = vote_k, vote_n

    def frame_values(self, evidence: StopEvidence, views: torch.Tensor) -> torch.Tensor:
        """(B,) the value each frame enters the soft maximum with (score, or gated score)."""
        if self.objective == "score":
            return evidence.score
        estimate_m = self.scene.bank.stop_line_estimate_m(views, evidence.box_height_px)
        return evidence.score * gate_weight(estimate_m, self.trigger_dist_m, self.gate_softness_m)

    def sequence_loss(self, texture: torch.Tensor, sequences: list[list[int]], generator: torch.Generator) -> torch.Tensor:
        """The objective on the given drive-bys (lists of view indices, far to near).

        Every frame is scored, but the detector's backward pass runs only through each
        sequence's `grad_frames` frames of highest value: with the soft maximum's temperature
        the others weigh next to nothing in its gradient (a frame 0.25 below the top one has
        e^-5 of its weight), and the backward pass is most of a step's cost. The loss's value
        is the whole sequence's.
        """
        views = [v for sequence in sequences for v in sequence]
        idx = torch.as_tensor(views)
        bank = self.scene.bank
        images = self.scene.images(texture, views, generator)
        boxes = bank.sign_box_px[idx]
        with torch.no_grad():
            values = self.frame_values(self.scene.target.evidence(images, boxes), idx)
        chosen, start = [], 0
        for sequence in sequences:
            top = torch.topk(values[start:start + len(sequence)], min(self.grad_frames, len(sequence))).indices
            chosen.append(top + start)
            start += len(sequence)
        chosen = torch.cat(chosen)
        evidence = self.scene.target.evidence(images[chosen], boxes[chosen])
        values = values.index_put((chosen,), self.frame_values(evidence, idx[chosen]))
        per_sequence = [kth_largest_in_windows(v, self.vote_k, self.vote_n) if self.vote_n > 1 else v
                        for v in values.split([len(s) for s in sequences])]
        loss = driveby_objective(per_sequence, self.temperature)
        if self.range_weight:
            loss = loss + self.range_weight * log_height_ratio(evidence.box_height_px, bank.true_height_px[idx[chosen]]).mean()
        return loss

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): within the SSIM floor, minimising
        the sequence loss (`sequence_loss`) over sampled whole drive-bys.
        """
        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            sequences = self.scene.sample_sequences(self.sequences_per_step, self.views_per_step, gen)
            return self.sequence_loss(texture, sequences, gen)

        return optimise_within_ssim(self, clean, self.eps, self.ssim_floor, generator, loss)
