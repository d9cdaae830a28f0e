"""The sign dataset: JSONL records -> letterboxed tensors and input-pixel targets.

A dataset directory DIR holds DIR/train.jsonl and DIR/val.jsonl, one JSON object per line:
  {"image": "images/train/000123.png", "boxes": [[x0, y0, x1, y1], ...],
   "classes": ["stop_sign", ...], "meta": {...}}
Image paths are relative to DIR (RGB PNG); boxes are continuous image pixels; sign-free
frames have empty lists; `meta` is not used for training.

Augmentation randomness is drawn per sample from SeedSequence([seed, epoch, index]):
deterministic, independent of visiting order and of DataLoader workers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from torch.utils.data import Dataset

from avsim.errors import AvsimError
from avsim.file_kinds import special_file_kind
from avsim.image_files import ImageError, check_image_file, decode_image
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.augment import AugmentConfig, clip_boxes, jitter_letterbox, photometric
from avsim.perception.detector.letterbox import fit, to_tensor, warp
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE
from avsim.validation import Range

SPLITS = ("train", "val")


class DatasetError(AvsimError):
    """A detector dataset that is missing, malformed or refers to missing images."""


@dataclass(frozen=True)
class Record:
    """One labelled image: boxes (G, 4) xyxy [image px], classes (G,) int64 indices into the class names;
    `where` is its labels line, FILE:LINE, for errors."""

    image_path: Path
    boxes: np.ndarray
    classes: np.ndarray
    where: str = ""


# Any finite number, not a bool (JSON true would otherwise pass as 1.0, and numpy reads "3" as 3.0).
FINITE = Range()
# The PNG IEND chunk (zero length, type, CRC): the last 12 bytes of every complete PNG.
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"
# A field's value when its key is absent, so the error says "is missing" and not "is null".
MISSING = object()


def _shown(value: object) -> str:
    """`value` as JSON, cut short: a field's bad value quoted in a one-line error."""
    if value is MISSING:
        return "missing"
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def field_error(where: str, name: str, value: object, expected: str) -> DatasetError:
    """The one-line error for labels line `where` whose field `name` holds `value` instead of `expected`."""
    return DatasetError(f"{where}: field '{name}' is {_shown(value)}, expected {expected}; fix the line or "
                        "regenerate the dataset with `avsim detector make-data`")


def parse_line(line: str, where: str, data_dir: Path, class_names: tuple[str, ...]) -> Record:
    """One JSONL line of a dataset (`where` names it in errors) as a `Record`: the image path under
    `data_dir`, the boxes (N, 4) xyxy [image px] and their class indices into `class_names`.

    Every field's type and shape is checked here, so a hand-edited line is one DatasetError naming
    FILE:LINE and the field, when the dataset is read, and never an internal error mid-training.
    """
    return parse_object(decode_line(line, where), where, data_dir, class_names)


def decode_line(line: str, where: str) -> Any:
    """The JSON value of labels line `where`, unchecked; a one-line DatasetError when it is not JSON."""
    try:
        return json.loads(line)
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{where} is not valid JSON ({exc.msg}); regenerate the dataset") from None


def parse_object(obj: object, where: str, data_dir: Path, class_names: tuple[str, ...]) -> Record:
    """`parse_line` for a line already decoded (`decode_line`), for a reader that also keeps the object;
    `obj` is only read, never changed."""
    if not isinstance(obj, dict) or not {"image", "boxes", "classes"} <= obj.keys():
        raise DatasetError(f"{where} needs the keys 'image', 'boxes' and 'classes'; regenerate the dataset")
    image, boxes, classes = obj["image"], obj["boxes"], obj["classes"]
    if not isinstance(image, str) or not image.strip():
        raise field_error(where, "image", image, "the image's path relative to the dataset folder")
    if not isinstance(boxes, list):
        raise field_error(where, "boxes", boxes, "a list of [x0, y0, x1, y1] boxes [image px]")
    for i, box in enumerate(boxes):
        if not isinstance(box, list) or len(box) != 4 or not all(FINITE.contains(v) for v in box):
            raise field_error(where, f"boxes[{i}]", box, "[x0, y0, x1, y1], four finite numbers [image px]")
        if not (box[0] < box[2] and box[1] < box[3]):
            raise field_error(where, f"boxes[{i}]", box, "x0 < x1 and y0 < y1 (x1 < x0 or y1 < y0 is a flipped box)")
    if not isinstance(classes, list) or not all(isinstance(c, str) for c in classes):
        raise field_error(where, "classes", classes, f"a list of class names ({', '.join(class_names)})")
    if len(boxes) != len(classes):
        raise DatasetError(f"{where} has {len(boxes)} boxes but {len(classes)} classes; regenerate the dataset")
    unknown = sorted({c for c in classes if c not in class_names})
    if unknown:
        raise DatasetError(f"{where} has unknown class {unknown[0]!r}; expected one of {', '.join(class_names)}")
    if not isinstance(obj.get("meta", {}), dict):  # training ignores meta, evaluation reads it by key
        raise field_error(where, "meta", obj["meta"], "an object such as {\"camera\": \"front\", ...}")
    box_array = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    class_array = np.array([class_names.index(c) for c in classes], dtype=np.int64)
    return Record(data_dir / image, box_array, class_array, where)


def _last_bytes(path: Path, size: int, n: int) -> bytes:
    """The last `n` bytes of the file `path` of `size` bytes, without reading the rest."""
    with path.open("rb") as f:
        f.seek(max(0, size - n))
        return f.read()


def check_image_files(records: list[Record]) -> None:
    """Refuse, in one line naming the labels line, an image that is missing, not a regular file,
    empty, or a PNG cut short: before training or scoring starts, not an epoch into it.

    Only the file's size and its last 12 bytes are read (a truncated PNG lacks its IEND chunk),
    never the pixels: decoding every image twice would double the cost of reading a large
    dataset, and an image that is complete but corrupt inside is still refused in one line
    when it is read (`read_rgb`).
    """
    for record in records:
        path = record.image_path
        try:
            if not path.is_file():
                kind = "a folder" if path.is_dir() else special_file_kind(path)
                problem = f"is {kind}, not a regular file" if kind else "does not exist"
            elif (size := path.stat().st_size) == 0:
                problem = "is empty"
            elif path.suffix.lower() == ".png" and _last_bytes(path, size, len(PNG_END)) != PNG_END:
                problem = "is cut short (it has no PNG end chunk)"
            else:
                continue
        except OSError as exc:
            raise DatasetError(f"{record.where}: cannot read image {path} ({exc.strerror})") from None
        raise DatasetError(f"{record.where}: image {path} {problem}; restore it, drop the line, or regenerate the "
                           "dataset with `avsim detector make-data`")


def split_path(data_dir: str | Path, split: str) -> Path:
    """`data_dir/<split>.jsonl`; a one-line DatasetError saying how to make the dataset when it is missing."""
    data_dir = Path(data_dir)
    path = data_dir / f"{split}.jsonl"
    if path.is_file():
        return path
    if data_dir.is_file():
        raise DatasetError(f"--data {data_dir} is a file; a detector dataset is a folder with train.jsonl and "
                           "val.jsonl (`avsim detector make-data --out FOLDER` makes one): point --data at it")
    if not data_dir.is_dir():
        raise DatasetError(f"no detector dataset at {data_dir} (a fresh clone has none); make one with "
                           f"`avsim detector make-data --out {data_dir}` (about 4.5 min), or point --data at one")
    raise DatasetError(f"detector dataset file {path} is missing; point --data at a directory with train.jsonl and "
                       f"val.jsonl, or remake it with `avsim detector make-data --out {data_dir} --overwrite`")


def read_records(data_dir: str | Path, split: str, class_names: tuple[str, ...] = SIGN_CLASSES) -> list[Record]:
    """All records of `split` ("train" or "val") in `data_dir`, validated."""
    if split not in SPLITS:
        raise DatasetError(f"unknown split '{split}'; expected one of {', '.join(SPLITS)}")
    data_dir = Path(data_dir)
    return [parse_line(line, where, data_dir, class_names) for where, line in split_lines(data_dir, split)]


def split_lines(data_dir: str | Path, split: str) -> list[tuple[str, str]]:
    """("FILE:LINE", text) of every non-blank line of the split's labels; a one-line DatasetError
    for a labels file that is not UTF-8 text or cannot be read."""
    path = split_path(data_dir, split)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path} is not a labels file (byte {exc.start} is not UTF-8 text); point --data at a "
                           "dataset made by `avsim detector make-data`") from None
    except OSError as exc:
        raise DatasetError(f"cannot read {path} ({exc.strerror})") from None
    return [(f"{path}:{n}", line) for n, line in enumerate(text.splitlines(), 1) if line.strip()]


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 RGB image from a PNG (OpenCV reads BGR)."""
    if not path.is_file():
        raise DatasetError(f"image {path} is missing or unreadable; regenerate the dataset")
    try:
        image = decode_image(check_image_file(path), path, cv2.IMREAD_COLOR)
    except ImageError as exc:  # too large (a decompression bomb), or not an image
        raise DatasetError(f"{exc}; regenerate the dataset") from None
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


class SignDataset(Dataset):
    """Item i -> (image (3, H_in, W_in) float32 in [0, 1], {"boxes": (G, 4) float32 xyxy [input px],
    "classes": (G,) int64}).

    augment: train-time augmentation (`augment.AugmentConfig`); call `set_epoch` each
    epoch so every epoch draws new augmentations.
    """

    def __init__(self, data_dir: str | Path, split: str = "train", input_size: tuple[int, int] = DEPLOY_INPUT_SIZE,
                 augment: bool = False, seed: int = 0, augment_config: AugmentConfig = AugmentConfig(),
                 class_names: tuple[str, ...] = SIGN_CLASSES) -> None:
        self.records = read_records(data_dir, split, class_names)
        check_image_files(self.records)  # a missing image is refused now, not when an epoch reaches it
        self.input_size = (int(input_size[0]), int(input_size[1]))
        self.augment = augment
        self.seed = int(seed)
        self.augment_config = augment_config
        self.class_names = class_names
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Set the epoch the augmentations are drawn for (each sample's randomness is seeded by seed, epoch, index)."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, index: int) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        record = self.records[index]
        image = read_rgb(record.image_path)
        h, w = image.shape[:2]
        box = fit(w, h, self.input_size)
        config = self.augment_config
        if self.augment:
            rng = np.random.default_rng(np.random.SeedSequence([self.seed, self.epoch, index]))
            box = jitter_letterbox(box, w, h, config, rng)
            image_in = photometric(warp(image, box), config, rng)
            boxes, classes = clip_boxes(box.to_input(record.boxes), record.classes, box.in_w, box.in_h,
                                        config.min_visible, config.min_box_px)
        else:
            image_in = warp(image, box)
            boxes, classes = clip_boxes(box.to_input(record.boxes), record.classes, box.in_w, box.in_h, 0.0, 1e-6)
        target = {"boxes": torch.from_numpy(boxes).float().reshape(-1, 4), "classes": torch.from_numpy(classes).long()}
        return to_tensor(image_in), target


def collate(batch: list[tuple[torch.Tensor, dict[str, torch.Tensor]]]) -> tuple[torch.Tensor, list[dict[str, torch.Tensor]]]:
    """Items -> (images (B, 3, H_in, W_in), per-image target dicts)."""
    images = torch.stack([image for image, _ in batch]).contiguous()
    return images, [target for _, target in batch]
