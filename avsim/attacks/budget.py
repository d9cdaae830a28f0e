"""Camouflage budgets and what they are measured with.

Textures are (3, H, W) float tensors in [0, 1], RGB. The budget keeps an attacked sign a
plain stop sign to a person: an L-infinity bound on the change (or a sticker-area bound),
and SSIM against the clean texture, reported for every result.
"""

from __future__ import annotations

import torch
from kornia.metrics import ssim as kornia_ssim

SSIM_WINDOW_PX = 11  # the usual Gaussian window (Wang et al. 2004)
SSIM_FLOOR = 0.7  # default budgets keep SSIM at or above this


def ssim(texture: torch.Tensor, clean: torch.Tensor, mask: torch.Tensor | None = None) -> float:
    """Mean SSIM of two (3, H, W) textures, over the sign face `mask` (1, H, W) when given."""
    ssim_map = kornia_ssim(texture[None].float(), clean[None].float(), SSIM_WINDOW_PX)[0]  # (3, H, W)
    if mask is None:
        return float(ssim_map.mean())
    weights = mask.expand_as(ssim_map)
    return float((ssim_map * weights).sum() / weights.sum().clamp(min=1))


def linf(texture: torch.Tensor, clean: torch.Tensor) -> float:
    """Largest per-channel change [0-1 units]."""
    return float((texture - clean).abs().amax())


def project_linf(delta: torch.Tensor, eps: float, clean: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The nearest perturbation that is within `eps`, zero outside the face `mask`, and keeps
    clean + delta inside [0, 1]."""
    delta = delta.clamp(-eps, eps) * mask
    return (clean + delta).clamp(0.0, 1.0) - clean


def total_variation(texture: torch.Tensor) -> torch.Tensor:
    """Mean absolute difference between neighbouring pixels of a (3, H, W) texture (RP2's smoothness term)."""
    dx = (texture[:, :, 1:] - texture[:, :, :-1]).abs().mean()
    dy = (texture[:, 1:, :] - texture[:, :-1, :]).abs().mean()
    return dx + dy


# A printer's reachable colours, coarsely (RGB in [0, 1]): primaries, secondaries, greys and
# the sign's own reds and whites. RP2 measured its palette from a real printer; this one is a stand-in.
PRINTABLE_RGB = torch.tensor([
    [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5], [0.25, 0.25, 0.25], [0.75, 0.75, 0.75],
    [0.8, 0.1, 0.1], [0.6, 0.05, 0.05], [0.95, 0.5, 0.5], [0.1, 0.6, 0.1], [0.1, 0.2, 0.7],
    [0.95, 0.85, 0.1], [0.9, 0.5, 0.1], [0.5, 0.1, 0.5], [0.1, 0.6, 0.6], [0.4, 0.25, 0.1],
])


def non_printability(texture: torch.Tensor, mask: torch.Tensor, palette: torch.Tensor = PRINTABLE_RGB) -> torch.Tensor:
    """RP2's non-printability score: mean over masked pixels of the product of distances
    to the palette's colours; zero where a pixel is exactly printable."""
    pixels = texture.permute(1, 2, 0)[mask[0] > 0.5]  # (P, 3)
    if pixels.numel() == 0:
        return texture.sum() * 0.0
    distances = torch.cdist(pixels, palette.to(texture))  # (P, colours)
    return distances.prod(dim=1).mean()


def within_ssim(clean: torch.Tensor, change: torch.Tensor, mask: torch.Tensor, floor: float,
                measure=None, iterations: int = 12) -> torch.Tensor:
    """The change scaled towards zero, as little as needed for SSIM(clean + change, clean) >= floor.

    clean, change: (3, H, W); mask: (1, H, W) the face SSIM is measured over. `measure(scaled
    change) -> SSIM` defaults to `ssim(clean + change, clean, mask)`; pass another to measure what
    will really be kept (e.g. the 8-bit PNG). The scale is found by bisection on [0, 1]
    (`iterations` halvings, then the feasible end), so the result always meets the floor if the
    unchanged texture does. Scaling a change towards the clean sign is the projection the
    drive-by attacks apply after every step: it keeps the change's direction and shrinks its size.
    """
    measure = measure or (lambda c: ssim((clean + c).clamp(0, 1), clean, mask))
    if measure(change) >= floor:
        return change
    low, high = 0.0, 1.0  # feasible, infeasible
    for _ in range(iterations):
        mid = (low + high) / 2
        if measure(change * mid) >= floor:
            low = mid
        else:
            high = mid
    return change * low
