"""The detectors an attack is optimised against (`avsim attack generate --detector NAME`).

Each target takes camera crops with the attacked sign drawn in, (B, 3, S, S) RGB in [0, 1],
and the sign's box in them, (B, 4) xyxy [crop px], and returns a `StopEvidence` per view,
differentiable in the pixels:
- `detector`: avsim's own sign detector, on the crop at the camera's resolution, as the
  closed loop runs it;
- `coco`: the COCO CenterNet port (`avsim.perception.coco`), fed as `perception.coco_input`
  = upscale feeds it in the loop: the crop enlarged `upscale` times with TensorFlow's
  bilinear resize, values 0-255. Its stop-sign heatmap (after the sigmoid, before peak
  extraction) is the score; its top and bottom edge distances give the box height;
- `yolo`: YOLOv3-tiny (`avsim.perception.yolo`), fed as `perception.yolo_input` = upscale
  feeds it in the loop: the crop enlarged `upscale` times (bilinear, half-pixel centres),
  values 0-255. The score is objectness x stop-sign probability of the rows whose predicted
  box centre lies near the sign, before NMS; their boxes give the height;
- `ensemble`: avsim's detector and coco; a view's score is a soft maximum of the two, so a
  step works on whichever detector still sees the sign, and the box height is their
  geometric mean;
- `ensemble_all`: the same over all three networks (detector, coco, yolo);
- `ensemble_all_2of3`: all three networks, a view's score the soft second-largest of their
  scores (`objective.soft_kth_largest`): what the 2-of-3 fusion (`perception.ensemble_fusion =
  k_of_n`, `ensemble_k = 2`) reports, so a step works on hiding the sign from two networks at
  once, which is all that vote needs, rather than from the one that sees it best.

Any of them can sit behind the perception's input purification (`perception.purify`, a
defence): `PurifiedTarget` runs the deployed JPEG codec or median filter on the views in the
forward pass and passes gradients straight through it (BPDA, `avsim.attacks.bpda`), the
adaptive attack against that defence (`avsim attack generate --purify jpeg`).

`weight_hashes()` names the weight files and their sha256, for the texture's metadata.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Protocol

import torch

from avsim.attacks.bpda import TensorFn, purifier_layer
from avsim.attacks.objective import (StopEvidence, cells_near_boxes, masked_max, reported_height_px, soft_kth_largest,
                                     soft_maximum, stop_evidence)
from avsim.config import PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.coco.labels import STOP_SIGN_CLASS_ID
from avsim.perception.coco.ops import upsample_bilinear_tf
from avsim.perception.detector.model import SignDetector
from avsim.perception.yolo.preprocess import resize_bilinear
from avsim.perception.yolo.infer import avsim_class_name

# Each target's networks, and for an ensemble how many of them must see the sign (its vote's k).
TARGET_MEMBERS = {"detector": ("detector",), "coco": ("coco",), "yolo": ("yolo",), "ensemble": ("detector", "coco"),
                  "ensemble_all": ("detector", "coco", "yolo"), "ensemble_all_2of3": ("detector", "coco", "yolo")}
TARGET_VOTE_K = {"ensemble_all_2of3": 2}
TARGET_NAMES = tuple(TARGET_MEMBERS)
# A CenterNet cell predicts the object whose centre it holds; cells this far outside the sign's
# box [crop px] are left to the attack too, as for the own detector's cells.
NEAR_MARGIN_PX = 8.0
# Soft maximum of the two detectors' scores in `ensemble` (about the larger one).
ENSEMBLE_TEMPERATURE = 0.05


class Target(Protocol):
    """A differentiable stop-sign detector an attack optimises against: views in, the sign's
    stop-sign evidence out (`StopEvidence`, every field (B,)), with gradients to the pixels."""

    name: str

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """Stop-sign evidence of views `images` (B, 3, H, W) RGB in [0, 1], each field (B,), from the
        detector's cells near each view's sign box `sign_boxes_px` (B, 4) xyxy [view px].
        """

    def weight_hashes(self) -> dict[str, str]:
        """Weight file name -> its sha256, for the texture's provenance record."""


def _frozen(module: torch.nn.Module) -> torch.nn.Module:
    module.eval()
    for parameter in module.parameters():
        parameter.requires_grad_(False)
    return module


def sha256_file(path: Path) -> str:
    """Hex sha256 of the file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class DetectorTarget:
    """avsim's sign detector (fused, frozen)."""

    name = "detector"

    def __init__(self, detector: SignDetector, weights_path: Path | None = None) -> None:
        self.detector = _frozen(detector)
        self.weights_path = weights_path

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """Evidence (each field (B,)) of views `images` (B, 3, H, W) in [0, 1] from the detector's
        cells near each sign box `sign_boxes_px` (B, 4) xyxy [view px]."""
        return stop_evidence(self.detector(images), self.detector.strides, sign_boxes_px)

    def weight_hashes(self) -> dict[str, str]:
        """The weights file's name -> its sha256 (empty when the detector came without a file)."""
        return {self.weights_path.name: sha256_file(self.weights_path)} if self.weights_path else {}


def square_crops(images: torch.Tensor, boxes: torch.Tensor, crop_px: int | None) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, 3, c, c) squares of side `crop_px` around each view's sign (clipped to the view) and the
    boxes in them; the views themselves when `crop_px` is None or not smaller than them."""
    size = images.shape[-1]
    if crop_px is None or crop_px >= size:
        return images, boxes
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    origins = (centres - crop_px / 2).round().clamp(0, size - crop_px).long()
    crops = torch.stack([image[:, int(y):int(y) + crop_px, int(x):int(x) + crop_px]
                         for image, (x, y) in zip(images, origins.tolist())])
    return crops, boxes - origins.repeat(1, 2).to(boxes.dtype)


class CocoTarget:
    """The COCO CenterNet, on each view's crop upscaled by `upscale` (2 = the loop's default).

    crop_px: the network sees a crop_px x crop_px square around the sign (clipped to the view)
    rather than the whole view; a multiple of 16 so that the upscaled input is a multiple of 32.
    The network costs about 4x per doubling of the side, and its cells near the sign see the
    same pixels either way apart from context (`tests/attacks/test_targets.py` measures the
    score against the closed loop's own runner).
    """

    name = "coco"

    def __init__(self, model, upscale: int = 2, crop_px: int | None = 128, cache_dir: Path | None = None) -> None:
        if crop_px is not None and crop_px % 16:
            raise ValueError(f"COCO target crop must be a multiple of 16 px, got {crop_px}")
        self.model = _frozen(model)
        self.upscale = upscale
        self.crop_px = crop_px
        self.cache_dir = cache_dir

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """Evidence (each field (B,)) of views `images` (B, 3, H, W) in [0, 1]: the stop-sign heatmap's
        best cell centred within NEAR_MARGIN_PX of each sign box `sign_boxes_px` (B, 4) xyxy [view px],
        and that box's height [view px]; score, objectness and class probability are one number here."""
        crops, boxes = square_crops(images, sign_boxes_px, self.crop_px)
        x = upsample_bilinear_tf(crops * 255.0, (self.upscale, self.upscale)) if self.upscale > 1 else crops * 255.0
        heatmap, wh = self.model.maps(x.contiguous(memory_format=torch.channels_last))
        stride = x.shape[-1] / heatmap.shape[-1]
        b, _, h, w = heatmap.shape
        rows, cols = torch.meshgrid(torch.arange(h, dtype=x.dtype), torch.arange(w, dtype=x.dtype), indexing="ij")
        # The graph puts a cell's box centre at (4 col, 4 row) input px (`coco.decode`).
        centres = torch.stack([cols.reshape(-1), rows.reshape(-1)], dim=1) * stride / self.upscale  # crop px
        near = cells_near_boxes(centres, boxes.to(x.dtype), NEAR_MARGIN_PX)
        score = heatmap[:, STOP_SIGN_CLASS_ID].reshape(b, -1)
        heights_px = (wh[:, 1] + wh[:, 3]).reshape(b, -1) / self.upscale
        best = masked_max(score, near, 0.0)
        logit = torch.logit(best.clamp(1e-6, 1 - 1e-6))
        return StopEvidence(best, best, best, logit, reported_height_px(heights_px, score, near))

    def weight_hashes(self) -> dict[str, str]:
        """The fetched CenterNet files' names -> their sha256 (as checked at install)."""
        from avsim.perception.coco import fetch

        return {name: digest for name, digest in fetch.MODEL_FILES.values()}


class YoloTarget:
    """YOLOv3-tiny, on each view's crop (as `CocoTarget`'s) upscaled by `upscale` (2 = the loop's default)."""

    name = "yolo"

    def __init__(self, model, upscale: int = 2, crop_px: int | None = 128) -> None:
        if crop_px is not None and crop_px * upscale % model.size_multiple_px:
            raise ValueError(f"YOLO target crop x upscale must be a multiple of {model.size_multiple_px} px, got "
                             f"{crop_px} x {upscale}")
        self.model = _frozen(model)
        self.upscale = upscale
        self.crop_px = crop_px
        self.stop_class = [avsim_class_name(name) for name in model.class_names].index("stop_sign")

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """Evidence (each field (B,)) of views `images` (B, 3, H, W) in [0, 1] from the decoded rows
        whose boxes are centred within NEAR_MARGIN_PX of each sign box `sign_boxes_px` (B, 4) xyxy
        [view px]: objectness x stop-sign probability, and the reported box's height [view px]."""
        crops, boxes = square_crops(images, sign_boxes_px, self.crop_px)
        x = crops * 255.0
        if self.upscale > 1:
            x = resize_bilinear(x, (x.shape[-2] * self.upscale, x.shape[-1] * self.upscale))
        decoded = self.model.decoded(x.contiguous(memory_format=torch.channels_last))
        rows_px = decoded.boxes_xyxy / self.upscale  # crop px
        # A row predicts the object its box is centred on: rows centred near the sign are the sign's.
        centres = ((rows_px[..., :2] + rows_px[..., 2:]) / 2).detach()
        low, high = boxes[:, None, :2] - NEAR_MARGIN_PX, boxes[:, None, 2:] + NEAR_MARGIN_PX
        near = ((centres >= low) & (centres <= high)).all(dim=-1)  # (B, N)
        objectness, class_prob = decoded.objectness, decoded.class_prob[..., self.stop_class]
        score = objectness * class_prob
        best = masked_max(score, near, 0.0)
        class_logit = masked_max(torch.logit(class_prob.clamp(1e-6, 1 - 1e-6)), near, -14.0)
        return StopEvidence(best, masked_max(objectness, near, 0.0), masked_max(class_prob, near, 0.0), class_logit,
                            reported_height_px(rows_px[..., 3] - rows_px[..., 1], score, near))

    def weight_hashes(self) -> dict[str, str]:
        """The fetched Darknet files' names -> their sha256 (as checked at install)."""
        from avsim.perception.yolo import fetch

        return {name: digest for name, digest in fetch.MODEL_FILES.values()}


class EnsembleTarget:
    """Several targets at once; see the module docstring. `vote_k`: how many members must see the
    sign (1: any of them, the OR fusion)."""

    name = "ensemble"

    def __init__(self, targets: list, vote_k: int = 1) -> None:
        if not 1 <= vote_k <= len(targets):
            raise ValueError(f"vote_k must be in [1, {len(targets)}], got {vote_k}")
        self.targets = targets
        self.vote_k = vote_k

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """Each member's evidence of `images` (B, 3, H, W) combined: a soft `vote_k`-th largest of
        the scores (a soft maximum for 1), the `vote_k`-th largest class logit, the geometric mean
        of the box heights [view px]; each field (B,)."""
        parts = [target.evidence(images, sign_boxes_px) for target in self.targets]

        def combine(field: str) -> torch.Tensor:
            return soft_kth_largest(torch.stack([getattr(p, field) for p in parts], dim=-1), self.vote_k,
                                    ENSEMBLE_TEMPERATURE)

        heights = torch.exp(torch.stack([torch.log(p.box_height_px.clamp(min=0.5)) for p in parts]).mean(dim=0))
        logits = torch.stack([p.class_logit for p in parts], dim=-1)
        return StopEvidence(combine("score"), combine("objectness"), combine("class_prob"),
                            logits.topk(self.vote_k, dim=-1).values[..., -1], heights)

    def weight_hashes(self) -> dict[str, str]:
        """Every member's weight files' names -> their sha256."""
        return {name: digest for target in self.targets for name, digest in target.weight_hashes().items()}


class PurifiedTarget:
    """`inner` behind a purification layer (`bpda.purifier_layer`): the views are purified as the
    deployed perception purifies its frames, then scored; gradients pass the purifier unchanged.

    The deployed perception purifies the whole camera frame; here each view's crop is, so JPEG's
    8 px blocks may fall on the sign differently than in the loop (the crop's origin is not
    aligned to the frame's block grid). The median filter is the same either way away from
    the crop's border.
    """

    def __init__(self, inner: Target, purify: TensorFn, purify_name: str) -> None:
        self.inner = inner
        self.purify = purify
        self.name = f"{inner.name}+{purify_name}"

    def evidence(self, images: torch.Tensor, sign_boxes_px: torch.Tensor) -> StopEvidence:
        """`inner`'s evidence of the purified views `images` (B, 3, H, W) in [0, 1]; each field (B,)."""
        return self.inner.evidence(self.purify(images), sign_boxes_px)

    def weight_hashes(self) -> dict[str, str]:
        """`inner`'s weight files (the purifier has none)."""
        return self.inner.weight_hashes()


def purified(target: Target, purify: PerceptionConfig | None) -> Target:
    """`target` behind `purify`'s purification; `target` itself when it purifies nothing."""
    if purify is None or purify.purify == "none":
        return target
    return PurifiedTarget(target, purifier_layer(purify), purify.purify)


def build_target(name: str, weights_path: str = "") -> Target:
    """The named target with the shipped (or given) detector weights and the fetched COCO files."""
    from avsim.perception.detector.weights import resolve_weights_path
    from avsim.perception.detector.weights import load_weights

    if name not in TARGET_NAMES:
        raise ConfigError(f"unknown attack target detector '{name}'; choose one of: {', '.join(TARGET_NAMES)}")

    def own() -> DetectorTarget:
        path = resolve_weights_path(weights_path)
        model, _ = load_weights(path)
        return DetectorTarget(model.fuse(), path)

    def coco() -> CocoTarget:
        from avsim.perception.coco.model import load_centernet

        return CocoTarget(load_centernet())

    def yolo() -> YoloTarget:
        from avsim.perception.yolo.model import load_yolo

        return YoloTarget(load_yolo())

    build = {"detector": own, "coco": coco, "yolo": yolo}
    members = [build[member]() for member in TARGET_MEMBERS[name]]
    if len(members) == 1:
        return members[0]
    return EnsembleTarget(members, TARGET_VOTE_K.get(name, 1))

