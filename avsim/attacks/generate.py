"""`avsim attack generate`: optimise one texture against the shipped detector and save it.

Attacks optimise a 128x128 copy of the clean texture (a stop sign is at most about 70 px
tall in the views that matter, so finer texels would only alias); the change is then
upsampled bilinearly onto the 512x512 clean texture. Bilinear weights are convex, so the
L-infinity bound survives the upsampling. SSIM and L-infinity are measured on the saved
texture, over the sign face.
"""

from __future__ import annotations

import hashlib
import inspect
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
import torch.nn.functional as F

from avsim.attacks.base import AttackResult
from avsim.attacks.budget import linf, ssim
from avsim.attacks.eot import EotScene
from avsim.attacks.registry import ATTACKS
from avsim.attacks.sign_view import face_alpha
from avsim.errors import ConfigError
from avsim.attacks.view_bank import ViewBankSpec, build_view_bank
from avsim.metrics import write_json_atomic
from avsim.perception.detector.weights import resolve_weights_path
from avsim.perception.detector.weights import load_weights
from avsim.world.signs import SIGN_SHAPES
from avsim.world.textures import TEXTURE_DIR, load_texture_png, save_texture_png

OPTIMISED_TEXTURE_PX = 128


def texture_tensor(rgb: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 -> (3, H, W) float in [0, 1]."""
    return torch.from_numpy(rgb).permute(2, 0, 1).float() / 255


def tensor_to_rgb(texture: torch.Tensor) -> np.ndarray:
    return (texture.clamp(0, 1) * 255).round().to(torch.uint8).permute(1, 2, 0).numpy()


def clean_stop_texture() -> np.ndarray:
    return load_texture_png(TEXTURE_DIR / "stop_sign.png")


def downsample(rgb: np.ndarray, size_px: int = OPTIMISED_TEXTURE_PX) -> torch.Tensor:
    # Area averaging is the box filter a mipmap level applies.
    return texture_tensor(cv2.resize(rgb, (size_px, size_px), interpolation=cv2.INTER_AREA))


def apply_change(clean_full: torch.Tensor, clean_small: torch.Tensor, attacked_small: torch.Tensor) -> torch.Tensor:
    """The attacked full-size texture: clean + bilinearly upsampled (attacked - clean), on the face only."""
    change = F.interpolate((attacked_small - clean_small)[None], size=clean_full.shape[-2:], mode="bilinear",
                           align_corners=False)[0]
    face = (face_alpha(SIGN_SHAPES["stop_sign"], *clean_full.shape[-2:]) > 0.5).float()
    return (clean_full + change * face).clamp(0, 1)


def load_detector(weights_path: str = ""):
    model, meta = load_weights(resolve_weights_path(weights_path))
    return model.fuse(), meta


@dataclass
class AttackSetup:
    """What every attack run needs, built once: the frozen detector, the clean texture at
    full and optimised size, and the EOT scene over a rendered view bank."""

    scene: EotScene
    clean_full_rgb: np.ndarray
    clean_small: torch.Tensor
    weights_path: Path
    bank_spec: ViewBankSpec


def prepare(weights_path: str = "", bank_spec: ViewBankSpec = ViewBankSpec()) -> AttackSetup:
    """Load the detector and render the view bank (about 40 s for the default front-camera
    bank; each further camera adds about as much again)."""
    detector, _ = load_detector(weights_path)
    clean_full_rgb = clean_stop_texture()
    clean_small = downsample(clean_full_rgb)
    scene = EotScene(build_view_bank(bank_spec, clean_small), detector)
    return AttackSetup(scene, clean_full_rgb, clean_small, resolve_weights_path(weights_path), bank_spec)


def check_hyperparameters(method: str, seed: int, hyperparameters: dict[str, Any]) -> None:
    """Raise ConfigError for an unknown attack or hyperparameter name, before any rendering."""
    attack_class = ATTACKS.get(method)
    try:
        inspect.signature(attack_class).bind(None, seed=seed, **hyperparameters)
    except TypeError as exc:
        raise ConfigError(f"bad hyperparameters for attack '{method}' ({exc}); see avsim/attacks/{method}.py") from None


def generate(method: str, out_png: str | os.PathLike, *, seed: int = 0, setup: AttackSetup | None = None,
             hyperparameters: dict[str, Any] | None = None, progress: bool = True) -> tuple[AttackResult, dict[str, Any]]:
    """Run `method` and write OUT.png and OUT.json (hyperparameters, seed, SSIM, L-inf, timing).

    setup: a `prepare()`d detector and view bank, shared across runs; built here when None.
    """
    hyperparameters = hyperparameters or {}
    check_hyperparameters(method, seed, hyperparameters)
    started = time.perf_counter()
    setup = setup or prepare()
    attack_class = ATTACKS.get(method)
    try:
        attack = attack_class(setup.scene, seed=seed, **hyperparameters)
    except ValueError as exc:
        raise ConfigError(f"bad hyperparameters for attack '{method}' ({exc}); see avsim/attacks/{method}.py") from None
    attack.progress = progress
    if progress:
        print(f"{attack!r} over {len(setup.scene.bank)} views", flush=True)
    result = attack(setup.clean_small)
    clean_full = texture_tensor(setup.clean_full_rgb)
    rgb = tensor_to_rgb(apply_change(clean_full, setup.clean_small, result.texture))
    saved = texture_tensor(rgb)  # measure what is on disk, after 8-bit rounding
    bank = setup.scene.bank
    face = (face_alpha(SIGN_SHAPES["stop_sign"], *clean_full.shape[-2:]) > 0.5).float()
    record = {
        **result.to_json_dict(),
        "ssim": round(ssim(saved, clean_full, face), 4),
        "linf": round(linf(saved, clean_full), 4),
        "optimised_ssim": round(result.ssim, 4),
        "paper": attack_class.paper,
        "detector_weights": setup.weights_path.name,
        "detector_weights_sha256": hashlib.sha256(setup.weights_path.read_bytes()).hexdigest(),
        # The spec carries the cameras; the counts show each camera's views really made the bank.
        "view_bank": {**asdict(setup.bank_spec), "views": len(bank),
                      "views_by_camera": {camera: bank.camera.count(camera) for camera in setup.bank_spec.cameras}},
        "seconds": round(time.perf_counter() - started, 1),
    }
    out_png = Path(out_png)
    save_texture_png(out_png, rgb)
    write_json_atomic(out_png.with_suffix(".json"), record)
    return result, record
