"""The expectation-over-transformation scene the attacks optimise through.

evidence(texture) = detector(photometric(composite(warp(texture, view), view))) for a batch
of views drawn from a `ViewBank` of real MuJoCo renders: the texture is warped by each
view's homography, lit by its fitted gain and offset, drawn over its background, passed
through random exposure, fog, blur, noise and JPEG, and scored by the frozen detector.
"""

from __future__ import annotations

import torch

from avsim.attacks.objective import StopEvidence, stop_evidence
from avsim.attacks.photometric import PhotometricRanges, apply_photometric
from avsim.attacks.view_bank import ViewBank
from avsim.attacks.warp import composite, warp_texture
from avsim.perception.detector.model import SignDetector


class EotScene:
    """Differentiable texture -> stop-sign evidence over sampled views.

    face_mask: (1, H_tex, W_tex) the sign outline on the texture square; attacks change
    texels only where it is 1.
    """

    def __init__(self, bank: ViewBank, detector: SignDetector, photometric: PhotometricRanges = PhotometricRanges(),
                 cameras: tuple[str, ...] | None = None) -> None:
        self.bank = bank
        self.detector = detector.eval()
        for parameter in self.detector.parameters():
            parameter.requires_grad_(False)
        self.photometric = photometric
        self.face_mask = (bank.alpha > 0.5).float()
        allowed = set(cameras) if cameras else set(bank.camera)
        self._views = [i for i in range(len(bank)) if bank.camera[i] in allowed]
        self._groups = [[i for i in g if i in set(self._views)] for g in bank.groups]
        self._groups = [g for g in self._groups if g]
        if not self._views:
            raise ValueError(f"the view bank has no views from cameras {sorted(allowed)}")

    def sample_views(self, n_views: int, generator: torch.Generator, sequence: bool = False) -> list[int]:
        """n view indices: independent draws, or (sequence) one group's drive-by, far to near."""
        if not sequence:
            picks = torch.randint(0, len(self._views), (n_views,), generator=generator)
            return [self._views[int(i)] for i in picks]
        group = self._groups[int(torch.randint(0, len(self._groups), (1,), generator=generator))]
        if len(group) <= n_views:
            return list(group)
        # Evenly spaced through the approach, from a random first frame: a video at a random phase.
        step = len(group) / n_views
        start = float(torch.rand(1, generator=generator)) * step
        return [group[int(start + k * step)] for k in range(n_views)]

    def images(self, texture: torch.Tensor, views: list[int], generator: torch.Generator,
               photometric: bool = True) -> torch.Tensor:
        """Camera crops (B, 3, S, S) in [0, 1] with `texture` (3, H_tex, W_tex) on the sign."""
        bank = self.bank
        idx = torch.as_tensor(views)
        warped, mask = warp_texture(texture, bank.alpha, bank.corners_px[idx], tuple(bank.backgrounds.shape[-2:]))
        background = bank.backgrounds[idx].float() / 255
        images = composite(warped, mask, background, bank.gain[idx], bank.offset[idx])
        return apply_photometric(images, self.photometric, generator) if photometric else images

    def evidence(self, texture: torch.Tensor, n_views: int, generator: torch.Generator,
                 sequence: bool = False) -> StopEvidence:
        """Stop-sign evidence (each (n_views,)) for `texture` in freshly sampled views."""
        views = self.sample_views(n_views, generator, sequence)
        images = self.images(texture, views, generator)
        outputs = self.detector(images)
        return stop_evidence(outputs, self.detector.strides, self.bank.sign_box_px[torch.as_tensor(views)])
