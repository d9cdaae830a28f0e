"""BPDA: gradients through a step that has none, for attacks that adapt to input purification.

Backward Pass Differentiable Approximation (Athalye, Carlini and Wagner, ICML 2018,
"Obfuscated gradients give a false sense of security"): run the real, non-differentiable step
in the forward pass (here the deployed JPEG codec or median filter, bit for bit as the
perception applies it), and treat it as the identity in the backward pass. Purifiers that
keep the image close to their input are near the identity, so the approximate gradient still
points where the attack must go; that is how the paper broke JPEG and smoothing defences.

    purify = purifier_layer(config.perception)        # [B, 3, H, W] in [0, 1] -> the same
    scores = detector(purify(frames_with_the_sign))    # gradients reach the texture

The attack code places the layer where the deployed perception purifies: on the whole camera
frame, after the sign is drawn into it and before the network.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from avsim.config import PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.purify import build_purifier, purify_tensor

TensorFn = Callable[[torch.Tensor], torch.Tensor]


class _IdentityBackward(torch.autograd.Function):
    """forward: `fn(x)`; backward: the incoming gradient, unchanged."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, fn: TensorFn) -> torch.Tensor:  # noqa: ARG004 - autograd's signature
        with torch.no_grad():
            out = fn(x)
        if out.shape != x.shape:
            raise ValueError(f"a BPDA step must keep the input's shape {tuple(x.shape)}, got {tuple(out.shape)}")
        return out

    @staticmethod
    def backward(ctx, grad_output: torch.Tensor) -> tuple[torch.Tensor, None]:  # noqa: ARG004
        return grad_output, None


def bpda(fn: TensorFn) -> TensorFn:
    """`fn` in the forward pass, the identity in the backward pass; fn must keep the tensor's shape."""
    return lambda x: _IdentityBackward.apply(x, fn)


def purifier_layer(config: PerceptionConfig) -> TensorFn:
    """The perception's configured purification (`perception.purify`) as a BPDA layer on images
    [B, 3, H, W] in [0, 1]; a ConfigError when the perception purifies nothing."""
    purifier = build_purifier(config)
    if purifier is None:
        raise ConfigError("perception.purify is none: there is no purification to attack through; "
                          "set perception.purify to jpeg or median")
    return bpda(lambda images: purify_tensor(images, purifier))
