"""`yang`: attention-weighted perturbation.

Paper: K. Yang, T. Tsai, H. Yu, T.-Y. Ho, Y. Jin, "Beyond Digital Domain: Fooling Deep
Learning Based Recognition System in Physical World", AAAI 2020 (targeted attention attack).
Attention: the detector's gradient saliency on the clean sign, |d score / d texture| averaged
over `saliency_views` EOT views, blurred and normalised to [0, 1].
Constraint: a per-texel L-infinity bound eps_peak * attention^gamma, so the budget lands where
the detector looks and is near zero elsewhere; the face-average bound is reported as
`mean_bound` in the result's derived figures.
Objective: the expected stop-sign score (objectness x class) over EOT views.
"""

from __future__ import annotations

import torch
from kornia.filters import gaussian_blur2d

from avsim.attacks.base import Attack, Scene, optimise_bounded


def saliency_attention(scene: Scene, clean: torch.Tensor, n_views: int, generator: torch.Generator,
                       blur_sigma_px: float = 4.0) -> torch.Tensor:
    """(1, H, W) in [0, 1]: blurred gradient magnitude of the stop-sign score on the clean texture."""
    texture = clean.clone().requires_grad_(True)
    scene.evidence(texture, n_views, generator).score.mean().backward()
    saliency = texture.grad.abs().sum(dim=0, keepdim=True)
    kernel = int(4 * blur_sigma_px) | 1
    saliency = gaussian_blur2d(saliency[None], (kernel, kernel), (blur_sigma_px, blur_sigma_px))[0] * scene.face_mask
    return saliency / saliency.amax().clamp(min=1e-12)


class Yang(Attack):
    """Targeted attention attack (Yang et al. 2020): a per-texel L-infinity bound eps_peak x
    attention^gamma, the attention being the detector's blurred saliency on the clean sign over
    `saliency_views` views; minimises the mean stop-sign score over EOT views. Call it on a clean
    texture (3, H, W) in [0, 1].
    """

    name = "yang"
    paper = "Yang et al. 2020, targeted attention attack"

    def __init__(self, scene: Scene, *, eps_peak: float = 0.27, gamma: float = 0.5, saliency_views: int = 32,
                 steps: int = 250, views_per_step: int = 8, lr: float = 0.01, seed: int = 0) -> None:
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, eps_peak=eps_peak,
                         gamma=gamma, saliency_views=saliency_views)
        self.eps_peak, self.gamma, self.saliency_views = eps_peak, gamma, saliency_views

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): a per-texel bound from the
        detector's saliency (records `mean_bound`), minimising the mean score over EOT views.
        """
        attention = saliency_attention(self.scene, clean, self.saliency_views, generator)
        bound = self.eps_peak * attention ** self.gamma
        mask = self.scene.face_mask
        self.derived["mean_bound"] = round(float((bound * mask).sum() / mask.sum()), 4)

        def loss(texture: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
            return self.scene.evidence(texture, self.views_per_step, gen).score.mean()

        return optimise_bounded(self, clean, bound, generator, loss)
