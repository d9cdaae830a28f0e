"""`avsim attack generate`: optimise one texture against a target detector and save it.

Attacks optimise a 128x128 copy of the clean texture (a stop sign is at most about 70 px
tall in the views that matter, so finer texels would only alias); the change is then
upsampled onto the 512x512 clean texture:
- bilinearly for a change of the whole face (bilinear weights are convex, so an L-infinity
  bound survives the upsampling);
- by nearest neighbour inside the attack's change mask for an area budget (stickers), so
  that no texel outside the mask changes, trimmed deterministically if the upsampled mask
  still covers more of the face than the budget allows.
The camouflage budget is then enforced on what is saved: if SSIM against the clean sign over
the face, measured on the 8-bit PNG, is below `ssim_floor`, the change is scaled back towards
the clean sign until it is not. SSIM and L-infinity in the record are the PNG's.

Every texture is written with a JSON record holding what regenerates it
(`avsim attack generate --from textures/NAME.json`): method, hyperparameters, seed, target
detector (and the input purification it is attacked through, if any), view bank, photometric
ranges, budget floor and torch thread count, with the
sha256 of every weight file used and the compute time.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
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
from avsim.attacks.budget import SSIM_FLOOR, linf, ssim, within_ssim
from avsim.attacks.eot import EotScene
from avsim.attacks.hyperparameters import check_hyperparameter_values
from avsim.attacks.photometric import CLOSED_LOOP_PHOTOMETRIC, PhotometricRanges
from avsim.attacks.registry import ATTACKS
from avsim.attacks.sign_view import face_alpha
from avsim.attacks.targets import TARGET_MEMBERS, TARGET_NAMES, build_target, purified, sha256_file
from avsim.attacks.view_bank import ViewBankSpec, build_view_bank, closed_loop_bank_spec
from avsim.config import PerceptionConfig, check_seed
from avsim.errors import ConfigError
from avsim.metrics import write_json_atomic
from avsim.attacks.defaults import CLOSED_LOOP_METHODS, DEFAULT_THREADS
from avsim.validation import Range, check_finite_tree
from avsim.perception.detector.weights import resolve_weights_path
from avsim.perception.detector.weights import load_weights
from avsim.world.signs import SIGN_SHAPES
from avsim.world.textures import TEXTURE_DIR, load_texture_png, save_texture_png

OPTIMISED_TEXTURE_PX = 128


def texture_tensor(rgb: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 -> (3, H, W) float in [0, 1]."""
    return torch.from_numpy(rgb).permute(2, 0, 1).float() / 255


def tensor_to_rgb(texture: torch.Tensor) -> np.ndarray:
    """(3, H, W) float texture in [0, 1] -> (H, W, 3) uint8 RGB image (clamped, rounded)."""
    return (texture.clamp(0, 1) * 255).round().to(torch.uint8).permute(1, 2, 0).numpy()


def clean_stop_texture() -> np.ndarray:
    """The clean stop-sign face, textures/stop_sign.png, as (H, W, 3) uint8 RGB."""
    return load_texture_png(TEXTURE_DIR / "stop_sign.png")


def downsample(rgb: np.ndarray, size_px: int = OPTIMISED_TEXTURE_PX) -> torch.Tensor:
    # Area averaging is the box filter a mipmap level applies.
    """(H, W, 3) uint8 RGB -> (3, size_px, size_px) float texture in [0, 1], by area averaging."""
    return texture_tensor(cv2.resize(rgb, (size_px, size_px), interpolation=cv2.INTER_AREA))


def face_mask_full(height_px: int, width_px: int) -> torch.Tensor:
    """(1, H, W) 0/1: the stop sign's face on a texture of this size."""
    return (face_alpha(SIGN_SHAPES["stop_sign"], height_px, width_px) > 0.5).float()


def trim_mask(mask: torch.Tensor, max_pixels: int) -> torch.Tensor:
    """(1, H, W) 0/1 mask with at most `max_pixels` ones: the last ones in raster order removed."""
    flat = mask.reshape(-1).clone()
    on = torch.nonzero(flat > 0.5).squeeze(1)
    if len(on) > max_pixels:
        flat[on[max_pixels:]] = 0.0
    return flat.reshape(mask.shape)


def apply_change(clean_full: torch.Tensor, clean_small: torch.Tensor, attacked_small: torch.Tensor,
                 change_mask: torch.Tensor | None = None, max_changed_fraction: float | None = None) -> torch.Tensor:
    """The attacked full-size texture (3, H, W).

    change_mask None: clean + bilinearly upsampled (attacked - clean), on the face only.
    change_mask (1, h, w) 0/1 on the small texture: inside its nearest-neighbour upsampling (on
    the face, at most `max_changed_fraction` of the face's texels) the attacked small texture,
    upsampled by nearest neighbour; the clean texture elsewhere.
    """
    face = face_mask_full(*clean_full.shape[-2:])
    if change_mask is None:
        change = F.interpolate((attacked_small - clean_small)[None], size=clean_full.shape[-2:], mode="bilinear",
                               align_corners=False)[0]
        return (clean_full + change * face).clamp(0, 1)
    mask = F.interpolate(change_mask[None].float(), size=clean_full.shape[-2:], mode="nearest")[0] * face
    if max_changed_fraction is not None:
        mask = trim_mask(mask, int(max_changed_fraction * float(face.sum())))
    patch = F.interpolate(attacked_small[None], size=clean_full.shape[-2:], mode="nearest")[0]
    return (clean_full * (1 - mask) + patch * mask).clamp(0, 1)


def within_budget_on_disk(clean_full: torch.Tensor, attacked_full: torch.Tensor, ssim_floor: float) -> np.ndarray:
    """The 8-bit texture to save: `attacked_full`, with its change scaled back towards the clean
    sign as little as needed for the PNG's SSIM over the face to be at least `ssim_floor`."""
    face = face_mask_full(*clean_full.shape[-2:])

    def on_disk(change: torch.Tensor) -> float:
        return ssim(texture_tensor(tensor_to_rgb(clean_full + change)), clean_full, face)

    change = within_ssim(clean_full, attacked_full - clean_full, face, ssim_floor, measure=on_disk, iterations=14)
    return tensor_to_rgb(clean_full + change)


def load_detector(weights_path: str = ""):
    """The own detector (fused for inference) from `weights_path` (default: the shipped weights) and its metadata."""
    model, meta = load_weights(resolve_weights_path(weights_path))
    return model.fuse(), meta


@dataclass
class AttackSetup:
    """What every attack run needs, built once: the frozen target detector, the clean texture
    at full and optimised size, and the EOT scene over a rendered view bank."""

    scene: EotScene
    clean_full_rgb: np.ndarray
    clean_small: torch.Tensor
    detector: str
    weight_hashes: dict[str, str]
    bank_spec: ViewBankSpec
    photometric: PhotometricRanges
    seconds: float  # to load the target and render the bank, wall clock
    cpu_seconds: float  # the same, CPU time of this process (the machine may be shared)
    # The defence's input purification the target sits behind (BPDA), as perception keys; {} for none.
    purify: dict[str, Any] = dataclasses.field(default_factory=dict)


PURIFY_KEYS = ("purify", "purify_jpeg_quality", "purify_median_kernel_px")


def purify_config(purify: dict[str, Any]) -> PerceptionConfig | None:
    """The perception purification that `purify` (a dict of PURIFY_KEYS, {} for none) describes,
    checked as a perception config is; a one-line ConfigError for a bad key or value."""
    if not purify:
        return None
    unknown = sorted(set(purify) - set(PURIFY_KEYS))
    if unknown:
        raise ConfigError(f"unknown purification key '{unknown[0]}'; the keys are {', '.join(PURIFY_KEYS)}")
    try:
        return dataclasses.replace(PerceptionConfig(), **purify)  # its checks raise ConfigError
    except TypeError as exc:
        raise ConfigError(f"bad purification keys {purify} ({exc})") from None


def purify_keys(name: str) -> dict[str, Any]:
    """The perception keys of the named purification (`--purify`) at the defaults the leaderboard
    deploys; {} for none."""
    if name == "none":
        return {}
    defaults = PerceptionConfig()
    keys = {**{key: getattr(defaults, key) for key in PURIFY_KEYS}, "purify": name}
    try:
        purify_config(keys)  # checks the name
    except ConfigError as exc:
        raise ConfigError(f"--purify {name}: {exc}") from None
    return keys


def prepare(weights_path: str = "", bank_spec: ViewBankSpec = ViewBankSpec(), detector: str = "detector",
            photometric: PhotometricRanges = PhotometricRanges(), purify: dict[str, Any] | None = None) -> AttackSetup:
    """Load the target and render the view bank (about 40 s for the study textures' front-camera
    bank; each further camera adds about as much again; the closed-loop drive-by bank is about
    three times as many views). purify: perception keys (PURIFY_KEYS) of an input purification
    to attack through by BPDA; None or {} for none."""
    started, started_cpu = time.perf_counter(), time.process_time()
    purify = dict(purify or {})
    target = purified(build_target(detector, weights_path), purify_config(purify))
    clean_full_rgb = clean_stop_texture()
    clean_small = downsample(clean_full_rgb)
    scene = EotScene(build_view_bank(bank_spec, clean_small), target, photometric)
    return AttackSetup(scene, clean_full_rgb, clean_small, detector, target.weight_hashes(), bank_spec, photometric,
                       time.perf_counter() - started, time.process_time() - started_cpu, purify)


def default_bank(method: str, cameras: tuple[str, ...], speed_kmh: float) -> tuple[ViewBankSpec, PhotometricRanges]:
    """The view bank and photometric ranges a method is optimised over by default: the closed
    loop's for the drive-by methods, the study textures' generic ones for the five families."""
    if method in CLOSED_LOOP_METHODS:
        return closed_loop_bank_spec(cameras, speed_kmh=speed_kmh), CLOSED_LOOP_PHOTOMETRIC
    return ViewBankSpec(cameras=cameras), PhotometricRanges()


def check_hyperparameters(method: str, seed: int, hyperparameters: dict[str, Any]) -> None:
    """Raise ConfigError for an unknown attack or hyperparameter name, before any rendering."""
    attack_class = ATTACKS.get(method)
    try:
        inspect.signature(attack_class).bind(None, seed=seed, **hyperparameters)
    except TypeError as exc:
        raise ConfigError(f"bad hyperparameters for attack '{method}' ({exc}); see avsim/attacks/{method}.py") from None
    check_hyperparameter_values(method, attack_class, hyperparameters)


def check_ssim_floor(ssim_floor: float) -> None:
    """Refuse a camouflage budget outside (0, 1) with a one-line ConfigError."""
    if not 0 < ssim_floor < 1:
        raise ConfigError(f"--ssim-floor must be in (0, 1) (the camouflage budget is {SSIM_FLOOR}), got {ssim_floor}")


def generate(method: str, out_png: str | os.PathLike, *, seed: int = 0, setup: AttackSetup | None = None,
             hyperparameters: dict[str, Any] | None = None, ssim_floor: float | None = None,
             threads: int = DEFAULT_THREADS, progress: bool = True) -> tuple[AttackResult, dict[str, Any]]:
    """Run `method` and write OUT.png and OUT.json (see the module docstring).

    setup: a `prepare()`d target and view bank, shared across runs; built here (the method's
    default bank, front camera, detector target) when None. ssim_floor: the budget on the PNG;
    None takes the method's own `ssim_floor` hyperparameter if it has one, else 0.7. threads:
    torch's intra-op threads, recorded, since the optimisation's sums (and so the texture's last
    bits) depend on them.
    """
    hyperparameters = hyperparameters or {}
    check_hyperparameters(method, seed, hyperparameters)
    if ssim_floor is None:
        declared = inspect.signature(ATTACKS.get(method)).parameters.get("ssim_floor")
        ssim_floor = hyperparameters.get("ssim_floor", declared.default if declared else SSIM_FLOOR)
    check_ssim_floor(ssim_floor)
    torch.set_num_threads(threads)
    if setup is None:
        bank_spec, photometric = default_bank(method, ("front",), 85.0)
        setup = prepare(bank_spec=bank_spec, photometric=photometric)
    started, started_cpu = time.perf_counter(), time.process_time()
    attack_class = ATTACKS.get(method)
    try:
        attack = attack_class(setup.scene, seed=seed, **hyperparameters)
    except ValueError as exc:
        raise ConfigError(f"bad hyperparameters for attack '{method}' ({exc}); see avsim/attacks/{method}.py") from None
    attack.progress = progress
    if progress:
        print(f"{attack!r} against {setup.detector} over {len(setup.scene.bank)} views", flush=True)
    result = attack(setup.clean_small)
    clean_full = texture_tensor(setup.clean_full_rgb)
    attacked_full = apply_change(clean_full, setup.clean_small, result.texture, result.change_mask,
                                 result.max_changed_fraction)
    rgb = within_budget_on_disk(clean_full, attacked_full, ssim_floor)
    saved = texture_tensor(rgb)  # measure what is on disk, after 8-bit rounding
    bank = setup.scene.bank
    face = face_mask_full(*clean_full.shape[-2:])
    changed = (saved - clean_full).abs().amax(dim=0) > 0
    record = {
        **result.to_json_dict(),
        "ssim": round(ssim(saved, clean_full, face), 4),
        "linf": round(linf(saved, clean_full), 4),
        "changed_fraction": round(float(changed.sum() / face.sum()), 4),
        "optimised_ssim": round(result.ssim, 4),
        "ssim_floor": ssim_floor,
        "paper": attack_class.paper,
        "detector": setup.detector,
        **({"purify": setup.purify} if setup.purify else {}),
        "weights_sha256": setup.weight_hashes,
        # The spec carries the cameras; the counts show each camera's views really made the bank.
        "view_bank": {**asdict(setup.bank_spec), "views": len(bank),
                      "views_by_camera": {camera: bank.camera.count(camera) for camera in setup.bank_spec.cameras}},
        "photometric": asdict(setup.photometric),
        "torch_threads": threads,
        "torch_version": torch.__version__,
        # The vector kernels torch chose on this CPU: a texture regenerates bit for bit only with the
        # same ones (and the same threads); with others, float sums round differently and the
        # optimisation drifts by a few levels (tests/attacks/test_regenerate.py measures it).
        "torch_cpu_capability": torch.backends.cpu.get_cpu_capability(),
        # Compute time: the bank (rendered once per setup) and the optimisation, on this machine;
        # wall clock, and this process's CPU time (the machine is shared: wall time depends on the others).
        "bank_seconds": round(setup.seconds, 1),
        "seconds": round(setup.seconds + time.perf_counter() - started, 1),
        "cpu_seconds": round(setup.cpu_seconds + time.process_time() - started_cpu, 1),
    }
    out_png = Path(out_png)
    save_texture_png(out_png, rgb)
    write_json_atomic(out_png.with_suffix(".json"), record)
    return result, record


@dataclass(frozen=True)
class Recipe:
    """Everything a texture's JSON record says about how to make it again."""

    method: str
    seed: int
    hyperparameters: dict[str, Any]
    detector: str
    bank_spec: ViewBankSpec
    photometric: PhotometricRanges
    ssim_floor: float
    threads: int
    weight_hashes: dict[str, str]
    purify: dict[str, Any] = dataclasses.field(default_factory=dict)


def _dataclass_from(kind, values: dict[str, Any], source: str, section: str):
    """`kind` (a recipe's ViewBankSpec or PhotometricRanges) from a record's `section` table; a one-line
    ConfigError that names `source` (the record) and the field where a value is missing, of the wrong type or
    outside its range (`kind` checks its ranges as it is built)."""
    names = {f.name: f for f in dataclasses.fields(kind)}
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise ConfigError(f"{source}: {section}: unknown keys {', '.join(unknown)}")
    try:
        return kind(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})
    except ConfigError as exc:  # names the field itself ("view bank seed must be ...")
        raise ConfigError(f"{source}: {exc}") from None
    except (TypeError, ValueError) as exc:  # a string where a number belongs
        raise ConfigError(f"{source}: {section}: {exc}") from None


def read_recipe(json_path: str | os.PathLike) -> Recipe:
    """The recipe in a texture's JSON record; a one-line ConfigError if it is not one."""
    path = Path(json_path)
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        check_finite_tree(record, f"--from {path}")  # JSON's NaN and Infinity, which Python's json accepts
        method, seed, hyper = record["method"], record["seed"], record["hyperparameters"]
        tables = {"hyperparameters": hyper, "view_bank": record["view_bank"],
                  "photometric": record.get("photometric", {}), "purify": record.get("purify", {})}
        detector = record.get("detector", "detector")
    except FileNotFoundError:
        raise ConfigError(f"--from {path}: no such file; give a texture's JSON record, e.g. textures/driveby_detector.json") from None
    except UnicodeDecodeError:
        raise ConfigError(f"--from {path}: not a texture record (not UTF-8 text); give the JSON written beside a texture") from None
    except IsADirectoryError:
        raise ConfigError(f"--from {path} is a folder; give a texture's JSON record, e.g. textures/driveby_detector.json") from None
    except OSError as exc:
        raise ConfigError(f"--from {path}: cannot read it ({exc.strerror})") from None
    except KeyError as exc:
        raise ConfigError(f"--from {path}: not a texture record written by `avsim attack generate` (it has no "
                          f"'{exc.args[0]}' field)") from None
    except (json.JSONDecodeError, TypeError, ValueError, AttributeError) as exc:  # a field of the wrong shape
        raise ConfigError(f"--from {path}: not a texture record written by `avsim attack generate` ({exc!r})") from None
    if "weights_sha256" not in record:
        # A record from before the drive-by rework: the generator that wrote it (its view bank, EOT
        # and hyperparameters) is gone. No shipped record is one any more; a user's may be.
        raise ConfigError(f"--from {path}: this record was written by the generator before the drive-by rework "
                          "(it names no weights_sha256) and today's generator cannot replay it; make a new texture "
                          f"with `avsim attack generate --method {method} --out NEW.png`")
    if not isinstance(method, str) or not isinstance(detector, str):
        raise ConfigError(f"--from {path}: method and detector must be names, got {method!r} and {detector!r}")
    check_seed(seed, f"--from {path}: seed")
    if detector not in TARGET_NAMES:
        raise ConfigError(f"--from {path}: unknown detector {detector!r}; choose one of: {', '.join(TARGET_NAMES)}")
    hashes = record["weights_sha256"]
    if not isinstance(hashes, dict) or not all(isinstance(v, str) or v is None for v in hashes.values()):
        raise ConfigError(f"--from {path}: weights_sha256 must map each weights file to its SHA-256 (or null), "
                          f"got {hashes!r}")
    for name, table in tables.items():
        if not isinstance(table, dict):
            raise ConfigError(f"--from {path}: {name} must be a table of its fields, got {table!r}")
    hyper, photometric, purify = dict(hyper), tables["photometric"], dict(tables["purify"])
    bank = {k: v for k, v in tables["view_bank"].items() if k not in ("views", "views_by_camera")}
    try:
        check_hyperparameters(method, seed, hyper)
    except ConfigError as exc:
        raise ConfigError(f"--from {path}: {exc}") from None
    try:
        purify_config(purify)
    except ConfigError as exc:
        raise ConfigError(f"--from {path}: purify: {exc}") from None
    ssim_floor = Range(0, 1, lo_open=True, hi_open=True).check(record.get("ssim_floor", SSIM_FLOOR), f"--from {path}: ssim_floor")
    threads = Range(1, 64, integer=True).check(record.get("torch_threads", DEFAULT_THREADS), f"--from {path}: torch_threads")
    return Recipe(method, seed, hyper, detector, _dataclass_from(ViewBankSpec, bank, f"--from {path}", "view_bank"),
                  _dataclass_from(PhotometricRanges, photometric, f"--from {path}", "photometric"),
                  float(ssim_floor), threads, hashes, purify)


def check_weights(recipe: Recipe, weights_path: str = "") -> None:
    """A one-line ConfigError when the weights here are not the ones the texture was made against."""
    from avsim.perception.coco import fetch
    from avsim.perception.yolo import fetch as yolo_fetch

    expected = {name: digest for name, digest in recipe.weight_hashes.items() if digest}
    actual = {}
    members = TARGET_MEMBERS[recipe.detector]
    if "detector" in members:
        path = resolve_weights_path(weights_path)
        actual[path.name] = sha256_file(path)
    if "coco" in members:
        json_path, bin_path = fetch.model_paths()
        actual[json_path.name], actual[bin_path.name] = sha256_file(json_path), sha256_file(bin_path)
    if "yolo" in members:
        actual |= {path.name: sha256_file(path) for path in yolo_fetch.model_paths()}
    different = sorted(name for name, digest in expected.items() if actual.get(name, digest) != digest)
    if different:
        raise ConfigError(f"the weights differ from those the texture was made against ({', '.join(different)}): "
                          "its record cannot regenerate it with these weights")


def generate_from(json_path: str | os.PathLike, out_png: str | os.PathLike, weights_path: str = "",
                  progress: bool = True) -> tuple[AttackResult, dict[str, Any]]:
    """Make a texture again from its JSON record (`--from`), into OUT.png and OUT.json."""
    recipe = read_recipe(json_path)
    check_weights(recipe, weights_path)
    check_ssim_floor(recipe.ssim_floor)
    torch.set_num_threads(recipe.threads)
    setup = prepare(weights_path, recipe.bank_spec, recipe.detector, recipe.photometric, recipe.purify)
    return generate(recipe.method, out_png, seed=recipe.seed, setup=setup, hyperparameters=recipe.hyperparameters,
                    ssim_floor=recipe.ssim_floor, threads=recipe.threads, progress=progress)
