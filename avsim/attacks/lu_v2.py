"""`lu_v2`: detector-targeted suppression over a drive-by sequence, large L-infinity budget.

Paper: J. Lu, H. Sibai, E. Fabry, "Adversarial Examples that Fool Detectors", arXiv:1712.02494
(2017); the study's "Lu v2" texture.
Objective: minimise the mean, over a video-like sequence of views (one approach from 60 m
to 10 m, as the car meets the sign), of the detector's stop-sign score
(objectness x class probability, maximum over the sign's cells).
Constraint: |delta| <= eps on the sign face (L-infinity), eps = 0.15 by default.
How it differs from `lu_v3`: v2 spends a larger budget on the average frame; v3 spends a
smaller, smoothed budget on the best-detected frame.
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene, optimise_bounded


class LuV2(Attack):
    """Lu, Sibai and Fabry 2017, the study's "v2": |delta| <= eps (L-infinity, [0, 1] colour units)
    on the face, minimising the mean stop-sign score over a drive-by sequence (60 m to 10 m).
    Call it on a clean texture (3, H, W) in [0, 1].
    """

    name = "lu_v2"
    paper = "Lu, Sibai, Fabry 2017, Adversarial examples that fool detectors"

    def __init__(self, scene: Scene, *, eps: float = 0.15, steps: int = 250, views_per_step: int = 8,
                 lr: float = 0.01, seed: int = 0) -> None:
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, eps=eps)
        self.eps = eps

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): |delta| <= eps on the face,
        minimising the mean stop-sign score over a drive-by sequence of views.
        """
        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            return self.scene.evidence(texture, self.views_per_step, gen, sequence=True).score.mean()

        return optimise_bounded(self, clean, self.eps * self.scene.face_mask, generator, loss)
