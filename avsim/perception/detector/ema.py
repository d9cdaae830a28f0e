"""Exponential moving average of model weights (as in YOLOv5's ModelEMA).

ema = d * ema + (1 - d) * weights after every optimiser step, with the decay ramped up
d = decay * (1 - exp(-updates / ramp_updates)) so early, poor weights fade quickly.
BatchNorm running statistics (float buffers) are averaged too; integer buffers are copied.
"""

from __future__ import annotations

import copy
import math

import torch
from torch import nn


class ModelEMA:
    """An averaged copy of `model` (`self.model`, always in eval mode, no gradients)."""

    def __init__(self, model: nn.Module, decay: float = 0.9995, ramp_updates: float = 1000.0) -> None:
        self.model = copy.deepcopy(model).eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.decay = decay
        self.ramp_updates = ramp_updates
        self.updates = 0

    def current_decay(self) -> float:
        """The decay of the next update: `decay` ramped up from 0 over the first `ramp_updates` updates."""
        return self.decay * (1.0 - math.exp(-self.updates / self.ramp_updates))

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        """Move the averaged weights towards `model`'s by the current decay (buffers that are not floats are copied)."""
        self.updates += 1
        d = self.current_decay()
        source = model.state_dict()
        for name, value in self.model.state_dict().items():
            if value.dtype.is_floating_point:
                value.mul_(d).add_(source[name].detach(), alpha=1.0 - d)
            else:
                value.copy_(source[name])

    def state_dict(self) -> dict:
        """The averaged model's weights and the update count, for a checkpoint."""
        return {"model": self.model.state_dict(), "updates": self.updates}

    def load_state_dict(self, state: dict) -> None:
        """Restore what `state_dict` returned."""
        self.model.load_state_dict(state["model"])
        self.updates = int(state["updates"])
