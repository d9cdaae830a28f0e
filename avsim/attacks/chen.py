"""`chen`: ShapeShifter-style whole-texture attack.

Paper: S.-T. Chen, C. Cornelius, J. Martin, D. H. Chau, "ShapeShifter: Robust Physical
Adversarial Attack on Faster R-CNN Object Detector", ECML PKDD 2018.
Objective: minimise the expected stop-sign class evidence over EOT views, plus a
similarity penalty c * mean(delta^2) to the clean sign (ShapeShifter's L2 term). The
evidence is the class logit, floored at `logit_floor` (a probability of about 0.05), since
the probability of a clean sign saturates and passes no gradient.
Constraint: the perturbation lives on the whole sign face, |delta| <= eps (L-infinity).
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene, optimise_bounded


class Chen(Attack):
    """ShapeShifter (Chen et al. 2018): the whole face perturbed, |delta| <= eps (L-infinity, in
    [0, 1] colour units), minimising the floored stop-sign logit over EOT views plus
    `similarity_weight` x mean(delta^2). Call it on a clean texture (3, H, W) in [0, 1].
    """

    name = "chen"
    paper = "Chen et al. 2018, ShapeShifter"

    def __init__(self, scene: Scene, *, eps: float = 0.15, similarity_weight: float = 0.1, logit_floor: float = -3.0,
                 steps: int = 250, views_per_step: int = 8, lr: float = 0.01, seed: int = 0) -> None:
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, eps=eps,
                         similarity_weight=similarity_weight, logit_floor=logit_floor)
        self.eps, self.similarity_weight, self.logit_floor = eps, similarity_weight, logit_floor

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): Adam on delta, |delta| <= eps on
        the face, minimising the floored class logit over EOT views plus the similarity penalty.
        """
        mask = self.scene.face_mask

        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            evidence = self.scene.evidence(texture, self.views_per_step, gen)
            similarity = ((texture - clean) ** 2 * mask).sum() / mask.sum() / 3
            return evidence.class_logit.clamp(min=self.logit_floor).mean() + self.similarity_weight * similarity

        return optimise_bounded(self, clean, self.eps * mask, generator, loss)
