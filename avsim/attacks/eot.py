"""The expectation-over-transformation scene the attacks optimise through.

evidence(texture) = target(photometric(composite(warp(texture, view), view))) for a batch
of views drawn from a `ViewBank` of real MuJoCo renders: the texture is warped by each
view's homography, lit by its fitted gain and offset, drawn over its background, passed
through the photometric transformations (`photometric`: a generic camera pipeline, or the
closed loop's own sensor) and scored by a frozen target detector (`targets`).

Views are drawn independently (`sample_views`) or as whole drive-by sequences
(`sample_sequences`): one group of the bank, every frame from far to near, as one car meets
the sign on one approach.
"""

from __future__ import annotations

import torch

from avsim.attacks.objective import StopEvidence
from avsim.attacks.photometric import PhotometricRanges, apply_photometric
from avsim.attacks.targets import DetectorTarget, Target
from avsim.attacks.view_bank import ViewBank
from avsim.attacks.warp import composite, warp_texture
from avsim.perception.detector.model import SignDetector

# Pixels around the sign's box inside which the face is drawn: bilinear sampling and the mip
# pyramid's box filter reach at most a pixel or two beyond the outline.
WINDOW_MARGIN_PX = 3


class EotScene:
    """Differentiable texture -> stop-sign evidence over sampled views.

    target: a `targets.Target`, or avsim's `SignDetector` itself (wrapped as the `detector` target).
    face_mask: (1, H_tex, W_tex) the sign outline on the texture square; attacks change
    texels only where it is 1.
    """

    def __init__(self, bank: ViewBank, target: Target | SignDetector, photometric: PhotometricRanges = PhotometricRanges(),
                 cameras: tuple[str, ...] | None = None) -> None:
        self.bank = bank
        self.target = DetectorTarget(target) if isinstance(target, SignDetector) else target
        self.photometric = photometric
        self.face_mask = (bank.alpha > 0.5).float()
        allowed = set(cameras) if cameras else set(bank.camera)
        self._views = [i for i in range(len(bank)) if bank.camera[i] in allowed]
        kept = set(self._views)
        self._groups = [g for g in ([i for i in group if i in kept] for group in bank.groups) if g]
        if not self._views:
            raise ValueError(f"the view bank has no views from cameras {sorted(allowed)}")

    @property
    def groups(self) -> list[list[int]]:
        """The drive-by sequences this scene samples from (view indices, far to near)."""
        return self._groups

    def sample_views(self, n_views: int, generator: torch.Generator, sequence: bool = False) -> list[int]:
        """n view indices: independent draws, or (sequence) one group's drive-by, far to near."""
        if not sequence:
            picks = torch.randint(0, len(self._views), (n_views,), generator=generator)
            return [self._views[int(i)] for i in picks]
        group = self._groups[int(torch.randint(0, len(self._groups), (1,), generator=generator))]
        return _evenly(group, n_views, generator)

    def sample_sequences(self, n_sequences: int, max_frames: int, generator: torch.Generator) -> list[list[int]]:
        """n whole drive-bys (groups drawn with replacement), each far to near; a drive-by longer
        than `max_frames` keeps every k-th frame from a random first one (a video at a random phase)."""
        picks = torch.randint(0, len(self._groups), (n_sequences,), generator=generator)
        return [_evenly(self._groups[int(i)], max_frames, generator) for i in picks]

    def images(self, texture: torch.Tensor, views: list[int], generator: torch.Generator,
               photometric: bool = True) -> torch.Tensor:
        """Camera crops (B, 3, S, S) in [0, 1] with `texture` (3, H_tex, W_tex) on the sign.

        The face is warped only inside a window around each view's sign (its box grown by
        `WINDOW_MARGIN_PX`, one window size for the batch) and pasted into the background:
        every pixel the face covers lies in it, and each pixel's value is the one a whole-crop
        warp gives (the warp samples at pixel centres, so an integer shift of the corners is an
        integer shift of the image; `tests/attacks/test_eot.py`), at a tenth of the cost.
        """
        bank = self.bank
        idx = torch.as_tensor(views)
        size = bank.backgrounds.shape[-1]
        boxes = bank.sign_box_px[idx]
        lo = (boxes[:, :2].floor() - WINDOW_MARGIN_PX).clamp(0, size).long()
        hi = (boxes[:, 2:].ceil() + WINDOW_MARGIN_PX).clamp(0, size).long()
        window = int((hi - lo).max()) if len(views) else 0
        origin = torch.minimum(lo, torch.full_like(lo, size - window))  # every window inside the crop
        corners = bank.corners_px[idx] - origin[:, None, :].to(bank.corners_px.dtype)
        warped, mask = warp_texture(texture, bank.alpha, corners, (window, window))
        background = bank.backgrounds[idx].float() / 255
        patches = torch.stack([background[i, :, y:y + window, x:x + window] for i, (x, y) in enumerate(origin.tolist())])
        lit = composite(warped, mask, patches, bank.gain[idx], bank.offset[idx])
        images = torch.stack([_pasted(background[i], lit[i], x, y) for i, (x, y) in enumerate(origin.tolist())])
        return apply_photometric(images, self.photometric, generator) if photometric else images

    def evidence_of(self, texture: torch.Tensor, views: list[int], generator: torch.Generator) -> StopEvidence:
        """Stop-sign evidence (each (len(views),)) for `texture` in the given views."""
        images = self.images(texture, views, generator)
        return self.target.evidence(images, self.bank.sign_box_px[torch.as_tensor(views)])

    def evidence(self, texture: torch.Tensor, n_views: int, generator: torch.Generator,
                 sequence: bool = False) -> StopEvidence:
        """Stop-sign evidence (each (n_views,)) for `texture` in freshly sampled views."""
        return self.evidence_of(texture, self.sample_views(n_views, generator, sequence), generator)


def _evenly(group: list[int], n: int, generator: torch.Generator) -> list[int]:
    """The whole group if it has at most n members; else n evenly spaced from a random phase."""
    if len(group) <= n:
        return list(group)
    step = len(group) / n
    start = float(torch.rand(1, generator=generator)) * step
    return [group[int(start + k * step)] for k in range(n)]


def _pasted(background: torch.Tensor, patch: torch.Tensor, x: int, y: int) -> torch.Tensor:
    """(3, S, S) background with (3, w, w) `patch` in place at column x, row y (differentiable in the patch)."""
    _, height, width = background.shape
    w = patch.shape[-1]
    return torch.nn.functional.pad(patch, (x, width - x - w, y, height - y - w)) + background * _outside(height, width, x, y, w)


def _outside(height: int, width: int, x: int, y: int, w: int) -> torch.Tensor:
    keep = torch.ones(1, height, width)
    keep[:, y:y + w, x:x + w] = 0
    return keep
