"""`range_inflation`: make the detector's box of the sign short, so the sign reads farther away.

Paper: K.-H. Chow, L. Liu, M. Loper, J. Bae, M. E. Gursoy, S. Truex, W. Wei, Y. Wu,
"Adversarial Objectness Gradient Attacks in Real-time Object Detection Systems" (TOG), IEEE
TPS-ISA 2020, attack a detector through the gradient of one chosen output of its dense
predictions (objectness for vanishing, class for mislabelling); this attack takes the same
route through the box-height output, aimed at the pinhole range d = H f / h that the study's
braking gate and its defence 1 (`adjusted`, a = v^2 / 2d) compute from the box height.
A box 20 % short reads 25 % far: the gate opens later and `adjusted` brakes softer.
Objective: the mean, over whole drive-by sequences (every frame at the loop's frame spacing),
of the log ratio of the predicted box height to the true one, for the box the sign's cells
would report (their heights weighted by their scores, as NMS keeps the best); the score itself
is left to be whatever it is.
Constraint: the camouflage budget, SSIM >= `ssim_floor` on the sign face (projected after every
step by scaling the change back towards the clean sign), and |delta| <= eps.
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene, optimise_within_ssim
from avsim.attacks.objective import log_height_ratio


class RangeInflation(Attack):
    """Box-height attack after Chow et al. 2020 (TOG): within SSIM >= `ssim_floor` on the face and
    |delta| <= eps, minimising the mean log(predicted / true box height [px]) over whole drive-bys,
    so the pinhole range d = H f / h reads long. Call it on a clean texture (3, H, W) in [0, 1].
    """

    name = "range_inflation"
    paper = "Chow et al. 2020, TOG (one dense output's gradient; here the box height)"

    def __init__(self, scene: Scene, *, ssim_floor: float = 0.7, eps: float = 0.5, sequences_per_step: int = 1,
                 steps: int = 300, views_per_step: int = 40, lr: float = 0.01, seed: int = 0) -> None:
        if not 0 < ssim_floor < 1 or not 0 < eps <= 1 or sequences_per_step < 1:
            raise ValueError("need 0 < ssim_floor < 1, 0 < eps <= 1 and sequences_per_step >= 1")
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, ssim_floor=ssim_floor,
                         eps=eps, sequences_per_step=sequences_per_step)
        self.ssim_floor, self.eps, self.sequences_per_step = ssim_floor, eps, sequences_per_step

    def height_loss(self, texture: torch.Tensor, views: list[int], generator: torch.Generator) -> torch.Tensor:
        """Mean log(predicted / true box height) over the given views."""
        evidence = self.scene.evidence_of(texture, views, generator)
        return log_height_ratio(evidence.box_height_px, self.scene.bank.true_height_px[torch.as_tensor(views)]).mean()

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): within the SSIM floor, minimising
        the mean log ratio of predicted to true box height over sampled drive-bys.
        """
        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            sequences = self.scene.sample_sequences(self.sequences_per_step, self.views_per_step, gen)
            return self.height_loss(texture, [v for s in sequences for v in s], gen)

        return optimise_within_ssim(self, clean, self.eps, self.ssim_floor, generator, loss)
