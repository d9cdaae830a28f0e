"""The attack interface, shaped like torchattacks: construct with hyperparameters, then call.

    attack = ATTACKS.get("lu_v2")(scene, steps=300, seed=0)
    result = attack(clean_texture)          # AttackResult: texture, SSIM, L-inf, loss history

`scene` is the expectation-over-transformation scene (`avsim.attacks.eot.EotScene`): it warps
a texture into sampled camera views, runs the detector and returns the stop-sign evidence.
Subclasses write only `forward`; the base class seeds the generator, keeps the detector
frozen, measures the budget and prints the hyperparameters in `repr`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Protocol

import torch

from avsim.attacks.budget import linf, ssim, within_ssim
from avsim.attacks.objective import StopEvidence


class Scene(Protocol):
    """What an attack sees of the world: the sign face's texel mask and the stop-sign evidence a
    texture earns in rendered views of the sign (`avsim.attacks.sign_view`, over a view bank).

    Textures are (3, H_tex, W_tex) RGB in [0, 1], in the sign texture's own pixels (row 0 at the
    top of the face); evidence is per view, as `StopEvidence` tensors of shape (n_views,).
    """

    face_mask: torch.Tensor  # (1, H_tex, W_tex) 1 on the sign face, 0 outside the octagon

    def evidence(self, texture: torch.Tensor, n_views: int, generator: torch.Generator,
                 sequence: bool = False) -> StopEvidence:
        """Stop-sign evidence (each field (n_views,)) for `texture` (3, H_tex, W_tex) in [0, 1] in views
        sampled with `generator`; `sequence` draws them from one drive-by, far to near.
        """

    def evidence_of(self, texture: torch.Tensor, views: list[int], generator: torch.Generator) -> StopEvidence:
        """Stop-sign evidence (each field (len(views),)) for `texture` in the given views of the bank."""

    def sample_sequences(self, n_sequences: int, max_frames: int, generator: torch.Generator) -> list[list[int]]:
        """`n_sequences` drive-bys as lists of view indices, far to near, each at most `max_frames` long."""


@dataclass
class AttackResult:
    """An attacked texture (3, H, W) in [0, 1] and how it was made."""

    texture: torch.Tensor
    method: str
    hyperparameters: dict[str, Any]
    seed: int
    ssim: float
    linf: float
    loss_history: list[float] = field(default_factory=list)
    # Figures the attack derived from its hyperparameters (e.g. yang's mean bound): recorded,
    # but not hyperparameters, so a texture regenerates from its hyperparameters alone.
    derived: dict[str, Any] = field(default_factory=dict)
    # (1, H, W) 0/1: the only texels the attack may change, when its budget is an area
    # (stickers); the full-size texture is then made with nearest-neighbour upsampling so
    # that the area holds on the saved PNG (`generate.apply_change`). None: the whole face.
    change_mask: torch.Tensor | None = None
    max_changed_fraction: float | None = None

    def to_json_dict(self) -> dict[str, Any]:
        """The texture's JSON record: method, hyperparameters, seed, SSIM and L-inf to the clean sign,
        final loss and steps run (and any derived figures); the texture itself is the PNG.
        """
        return {"method": self.method, "hyperparameters": self.hyperparameters, "seed": self.seed,
                "ssim": self.ssim, "linf": self.linf, "final_loss": self.loss_history[-1] if self.loss_history else None,
                "steps_run": len(self.loss_history), **({"derived": self.derived} if self.derived else {})}


class Attack(ABC):
    """Base class. `paper` names the work the attack follows; subclasses set it."""

    name: str = ""
    paper: str = ""

    def __init__(self, scene: Scene, *, steps: int, views_per_step: int, lr: float, seed: int, **hyperparameters: Any) -> None:
        if steps < 1 or views_per_step < 1 or lr <= 0:
            raise ValueError(f"{self.name}: need steps >= 1, views_per_step >= 1 and lr > 0")
        self.scene = scene
        self.steps = steps
        self.views_per_step = views_per_step
        self.lr = lr
        self.seed = seed
        self.hyperparameters = {"steps": steps, "views_per_step": views_per_step, "lr": lr, **hyperparameters}
        self.loss_history: list[float] = []
        self.derived: dict[str, Any] = {}
        self.change_mask: torch.Tensor | None = None
        self.max_changed_fraction: float | None = None
        self.progress = False  # a progress bar over the steps (the CLI turns it on)

    def step_range(self):
        """range(self.steps), wrapped in a progress bar showing the loss when `progress` is on."""
        from tqdm import tqdm

        return tqdm(range(self.steps), desc=self.name, disable=not self.progress, dynamic_ncols=True)

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v}" for k, v in self.hyperparameters.items())
        return f"{type(self).__name__}({args}, seed={self.seed})"

    @abstractmethod
    def forward(self, clean: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """The attacked texture (3, H, W) in [0, 1]; append each step's loss to `self.loss_history`."""

    def __call__(self, clean: torch.Tensor) -> AttackResult:
        self.loss_history = []
        generator = torch.Generator().manual_seed(self.seed)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)  # nothing should read it; this makes sure nothing leaks either way
            texture = self.forward(clean.detach().float(), generator).detach().clamp(0.0, 1.0)
        mask = self.scene.face_mask
        return AttackResult(texture=texture, method=self.name, hyperparameters=dict(self.hyperparameters), seed=self.seed,
                            ssim=ssim(texture, clean, mask), linf=linf(texture, clean), loss_history=list(self.loss_history),
                            derived=dict(self.derived), change_mask=self.change_mask,
                            max_changed_fraction=self.max_changed_fraction)

    def _log(self, loss: torch.Tensor) -> None:
        value = float(loss.detach())
        if value != value:  # NaN
            raise FloatingPointError(f"{self.name}: loss became NaN at step {len(self.loss_history) + 1}")
        self.loss_history.append(value)


def optimise_bounded(attack: Attack, clean: torch.Tensor, bound: torch.Tensor, generator: torch.Generator,
                     loss_fn) -> torch.Tensor:
    """Adam on a perturbation delta kept inside a per-pixel bound, projected after every step.

    bound: (1 or 3, H, W) the largest |delta| allowed at each texel (0 off the face);
    loss_fn(texture, generator) -> scalar to minimise. Returns clean + delta, in [0, 1].
    """
    def project(delta: torch.Tensor) -> torch.Tensor:
        delta = torch.maximum(torch.minimum(delta, bound), -bound)
        return (clean + delta).clamp(0.0, 1.0) - clean

    return _optimise_projected(attack, clean, generator, loss_fn, project)


def optimise_within_ssim(attack: Attack, clean: torch.Tensor, eps: float, ssim_floor: float, generator: torch.Generator,
                         loss_fn) -> torch.Tensor:
    """Adam on a perturbation delta of the face, kept inside the camouflage budget after every
    step: |delta| <= eps, clean + delta in [0, 1], and SSIM(clean + delta, clean) >= ssim_floor
    on the face (`budget.within_ssim`: the change scaled back towards the clean sign).

    loss_fn(texture, generator) -> scalar to minimise. Returns clean + delta.
    """
    mask = attack.scene.face_mask

    def project(delta: torch.Tensor) -> torch.Tensor:
        change = (clean + delta.clamp(-eps, eps) * mask).clamp(0.0, 1.0) - clean
        return within_ssim(clean, change, mask, ssim_floor)

    return _optimise_projected(attack, clean, generator, loss_fn, project)


def _optimise_projected(attack: Attack, clean: torch.Tensor, generator: torch.Generator, loss_fn,
                        project) -> torch.Tensor:
    """Adam on a perturbation delta of `clean`, with delta replaced by project(delta) after every
    step (the constraint's projection, under no_grad). Returns clean + delta."""
    delta = torch.zeros_like(clean, requires_grad=True)
    optimizer = torch.optim.Adam([delta], lr=attack.lr)
    bar = attack.step_range()
    for _ in bar:
        loss = loss_fn(clean + delta, generator)
        attack._log(loss)
        bar.set_postfix(loss=f"{attack.loss_history[-1]:.4f}", refresh=False)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        with torch.no_grad():
            delta.copy_(project(delta))
    return (clean + delta).detach()
