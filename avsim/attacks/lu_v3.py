"""`lu_v3`: detector-targeted suppression of the best-detected frame, small smoothed budget.

Paper: J. Lu, H. Sibai, E. Fabry, "Adversarial Examples that Fool Detectors", arXiv:1712.02494
(2017); the study's "Lu v3" texture.
Objective: minimise a soft maximum (log-sum-exp, temperature `temperature`) over a
video-like drive-by sequence of the detector's stop-sign score, so the frame that would
trigger the brake first is the one pushed down; plus tv_weight * total variation, which
keeps the perturbation smooth and inconspicuous.
Constraint: |delta| <= eps on the sign face (L-infinity), eps = 0.12 by default.
How it differs from `lu_v2`: a smaller budget (0.12 against 0.15), a worst-frame rather
than mean-frame objective, and a smoothness term.
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene, optimise_bounded
from avsim.attacks.budget import total_variation


class LuV3(Attack):
    """Lu, Sibai and Fabry 2017, the study's "v3": |delta| <= eps (L-infinity, [0, 1] colour units)
    on the face, minimising a soft maximum (log-sum-exp at `temperature`) of the stop-sign score
    over a drive-by sequence plus `tv_weight` x total variation. Call it on a clean texture
    (3, H, W) in [0, 1].
    """

    name = "lu_v3"
    paper = "Lu, Sibai, Fabry 2017, Adversarial examples that fool detectors"

    def __init__(self, scene: Scene, *, eps: float = 0.12, temperature: float = 0.05, tv_weight: float = 0.05,
                 steps: int = 250, views_per_step: int = 8, lr: float = 0.01, seed: int = 0) -> None:
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, eps=eps,
                         temperature=temperature, tv_weight=tv_weight)
        self.eps, self.temperature, self.tv_weight = eps, temperature, tv_weight

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): |delta| <= eps on the face,
        minimising the soft maximum of the score over a drive-by sequence plus total variation.
        """
        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            score = self.scene.evidence(texture, self.views_per_step, gen, sequence=True).score
            soft_max = self.temperature * torch.logsumexp(score / self.temperature, dim=0)
            return soft_max + self.tv_weight * total_variation(texture - clean)

        return optimise_bounded(self, clean, self.eps * self.scene.face_mask, generator, loss)
