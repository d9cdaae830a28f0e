"""`eykholt`: RP2-style sticker attack.

Paper: K. Eykholt, I. Evtimov, E. Fernandes, B. Li, A. Rahmati, C. Xiao, A. Prakash,
T. Kohno, D. Song, "Robust Physical-World Attacks on Deep Learning Visual Classification",
CVPR 2018 (and the detector follow-up, "Physical Adversarial Examples for Object
Detectors", WOOT 2018).
Objective: the expected stop-sign score over EOT views, plus nps_weight * the
non-printability score of the sticker texels, plus tv_weight * their total variation,
plus norm_weight * mean(M * delta)^2 (RP2's lambda ||M delta||).
Constraint: a sticker mask M of `n_stickers` rectangles covering at most `max_area_fraction`
of the sign face; inside it the sticker may take any colour, outside it nothing changes.
Like RP2's graffiti-style masks, the stickers are horizontal bars above and below the legend.
"""

from __future__ import annotations

import torch

from avsim.attacks.base import Attack, Scene
from avsim.attacks.budget import non_printability, total_variation


def sticker_mask(face_mask: torch.Tensor, n_stickers: int, max_area_fraction: float, generator: torch.Generator) -> torch.Tensor:
    """(1, H, W) 0/1 mask of horizontal bars inside the face, `max_area_fraction` of its area at most.

    Bars sit in the top and bottom thirds of the face (the legend STOP is in the middle third),
    at seeded horizontal offsets; each bar is one-tenth of the face height tall.
    """
    _, h, w = face_mask.shape
    ys, xs = torch.nonzero(face_mask[0] > 0.5, as_tuple=True)
    top, bottom, left, right = int(ys.min()), int(ys.max()), int(xs.min()), int(xs.max())
    face_h, face_w = bottom - top + 1, right - left + 1
    bar_h = max(1, face_h // 10)
    budget_px = max_area_fraction * float(face_mask.sum())
    bar_w = int(min(0.45 * face_w, budget_px / max(n_stickers, 1) / bar_h))
    mask = torch.zeros_like(face_mask)
    for i in range(n_stickers):
        band_top = top + (face_h // 8 if i % 2 == 0 else 3 * face_h // 4)
        y0 = band_top + int(torch.randint(0, max(1, face_h // 12), (1,), generator=generator))
        x0 = left + int(torch.randint(face_w // 8, max(face_w // 8 + 1, face_w - bar_w - face_w // 8), (1,), generator=generator))
        mask[:, y0:y0 + bar_h, x0:x0 + bar_w] = 1.0
    return mask * (face_mask > 0.5)


class Eykholt(Attack):
    """RP2 stickers (Eykholt et al. 2018): `n_stickers` horizontal bars covering at most
    `max_area_fraction` of the face (an area budget, no norm bound inside it), minimising the mean
    stop-sign score over EOT views plus non-printability, total-variation and squared-change
    terms. Call it on a clean texture (3, H, W) in [0, 1].
    """

    name = "eykholt"
    paper = "Eykholt et al. 2018, RP2"

    def __init__(self, scene: Scene, *, n_stickers: int = 4, max_area_fraction: float = 0.12, nps_weight: float = 0.05,
                 tv_weight: float = 0.1, norm_weight: float = 0.01, steps: int = 250, views_per_step: int = 8,
                 lr: float = 0.03, seed: int = 0) -> None:
        super().__init__(scene, steps=steps, views_per_step=views_per_step, lr=lr, seed=seed, n_stickers=n_stickers,
                         max_area_fraction=max_area_fraction, nps_weight=nps_weight, tv_weight=tv_weight,
                         norm_weight=norm_weight)
        self.n_stickers, self.max_area_fraction = n_stickers, max_area_fraction
        self.nps_weight, self.tv_weight, self.norm_weight = nps_weight, tv_weight, norm_weight

    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """`clean` (3, H, W) in [0, 1] -> the attacked texture (3, H, W): stickers of free colour inside a
        random sticker mask (sets `change_mask`), minimising the score plus NPS, TV and norm terms.
        """
        mask = sticker_mask(self.scene.face_mask, self.n_stickers, self.max_area_fraction, generator)
        # The area budget must hold on the saved full-size texture too (`generate.apply_change`).
        self.change_mask, self.max_changed_fraction = mask, self.max_area_fraction
        # Stickers are solid material: optimise their colour freely, through a sigmoid to stay in [0, 1].
        logits = torch.logit(clean.clamp(0.02, 0.98)).clone().requires_grad_(True)
        optimizer = torch.optim.Adam([logits], lr=self.lr * 10)
        bar = self.step_range()
        for _ in bar:
            texture = clean * (1 - mask) + torch.sigmoid(logits) * mask
            evidence = self.scene.evidence(texture, self.views_per_step, generator)
            loss = (evidence.score.mean() + self.nps_weight * non_printability(texture, mask)
                    + self.tv_weight * total_variation(texture * mask)
                    + self.norm_weight * (((texture - clean) * mask) ** 2).mean())
            self._log(loss)
            bar.set_postfix(loss=f"{self.loss_history[-1]:.4f}", refresh=False)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
        return (clean * (1 - mask) + torch.sigmoid(logits) * mask).detach()
