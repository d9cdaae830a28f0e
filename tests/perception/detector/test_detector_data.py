"""The JSONL dataset: parsing, exact boxes under augmentation, seeded determinism, clear errors."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from avsim.errors import AvsimError
from avsim.perception.detector.augment import AugmentConfig
from avsim.perception.detector.data import DatasetError, SignDataset, collate

NO_PHOTOMETRIC = AugmentConfig(scale_prob=1.0, hue_shift=0.0, saturation_gain=(1.0, 1.0), value_gain=(1.0, 1.0),
                               contrast=(1.0, 1.0), brightness=(0.0, 0.0), blur_prob=0.0, noise_prob=0.0)


def _write(root: Path, records: list[dict], images: dict[str, np.ndarray], split: str = "train") -> Path:
    for rel, image in images.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / rel), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    (root / f"{split}.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return root


def test_items_match_the_jsonl(synthetic_dataset):
    dataset = SignDataset(synthetic_dataset, "val")
    lines = [json.loads(line) for line in (synthetic_dataset / "val.jsonl").read_text().splitlines()]
    assert len(dataset) == len(lines)
    image, target = dataset[0]
    assert image.shape == (3, 480, 640) and image.dtype == torch.float32 and 0 <= image.min() and image.max() <= 1
    for i, line in enumerate(lines):
        _, target = dataset[i]
        np.testing.assert_allclose(target["boxes"].numpy(), np.asarray(line["boxes"]).reshape(-1, 4), atol=1e-4)
        assert [("stop_sign", "yield", "speed_limit")[c] for c in target["classes"].tolist()] == line["classes"]
    images, targets = collate([dataset[0], dataset[1]])
    assert images.shape == (2, 3, 480, 640) and len(targets) == 2


def test_scale_jitter_moves_boxes_with_the_pixels(tmp_path):
    image = np.zeros((480, 640, 3), np.uint8)
    image[200:260, 300:340] = 255  # box [300, 200, 340, 260]
    root = _write(tmp_path, [{"image": "a.png", "boxes": [[300, 200, 340, 260]], "classes": ["yield"], "meta": {}}], {"a.png": image})
    dataset = SignDataset(root, "train", augment=True, seed=3, augment_config=NO_PHOTOMETRIC)
    seen_scales = set()
    for epoch in range(6):
        dataset.set_epoch(epoch)
        tensor, target = dataset[0]
        (x0, y0, x1, y1), = target["boxes"].numpy()
        seen_scales.add(round(float(y1 - y0), 3))
        bright = tensor[0].numpy() > 0.5
        rows, cols = np.where(bright.any(axis=1))[0], np.where(bright.any(axis=0))[0]
        assert abs(cols[0] - x0) <= 1.0 and abs(cols[-1] + 1 - x1) <= 1.0
        assert abs(rows[0] - y0) <= 1.0 and abs(rows[-1] + 1 - y1) <= 1.0
    assert len(seen_scales) > 1


def test_augmentation_is_seeded_per_epoch_and_index(synthetic_dataset):
    a = SignDataset(synthetic_dataset, "train", augment=True, seed=7)
    b = SignDataset(synthetic_dataset, "train", augment=True, seed=7)
    a.set_epoch(2)
    b.set_epoch(2)
    for i in (0, 5):
        (ia, ta), (ib, tb) = a[i], b[i]
        assert torch.equal(ia, ib) and torch.equal(ta["boxes"], tb["boxes"])
    b.set_epoch(3)
    assert not torch.equal(a[0][0], b[0][0])


def test_boxes_mostly_outside_the_crop_are_dropped(tmp_path):
    image = np.zeros((480, 640, 3), np.uint8)
    root = _write(tmp_path, [{"image": "a.png", "boxes": [[630, 10, 650, 30], [100, 100, 120, 130]],
                              "classes": ["stop_sign", "yield"], "meta": {}}], {"a.png": image})
    _, target = SignDataset(root, "train")[0]
    assert target["boxes"].shape == (2, 4)  # without augmentation only clipping
    assert target["boxes"][0, 2] == 640
    config = AugmentConfig(scale_prob=0.0, min_visible=0.6)
    _, target = SignDataset(root, "train", augment=True, augment_config=config)[0]
    assert target["classes"].tolist() == [1]


@pytest.mark.parametrize("line, match", [
    ("{not json", "not valid JSON"),
    ('{"image": "a.png", "boxes": [[0, 0, 1, 1]], "classes": ["pizza"]}', "unknown class 'pizza'"),
    ('{"image": "a.png", "boxes": [[0, 0, 1, 1]], "classes": []}', "1 boxes but 0 classes"),
    ('{"image": "a.png", "boxes": [[5, 0, 1, 1]], "classes": ["yield"]}', "'boxes[0]' is [5, 0, 1, 1], expected x0 < x1"),
    ('{"boxes": []}', "needs the keys"),
    ('["image", "boxes", "classes"]', "needs the keys"),
    # Wrong types, each an internal error (TypeError) before these checks:
    ('{"image": 5, "boxes": [], "classes": []}', "field 'image' is 5"),
    ('{"image": "a.png", "boxes": [[0, 0, 1, 1]], "classes": [["stop_sign"]]}', "field 'classes' is [[\"stop_sign\"]]"),
    ('{"image": "a.png", "boxes": 5, "classes": 5}', "field 'boxes' is 5"),
    # Numbers numpy would have read anyway ("1" as 1.0, true as 1.0), and two boxes in one:
    ('{"image": "a.png", "boxes": [["0", 0, 1, 1]], "classes": ["yield"]}', "field 'boxes[0]'"),
    ('{"image": "a.png", "boxes": [[true, 0, 1, 1]], "classes": ["yield"]}', "field 'boxes[0]'"),
    ('{"image": "a.png", "boxes": [[0, 0, 1, 1, 2, 2, 3, 3]], "classes": ["yield"]}', "field 'boxes[0]'"),
    ('{"image": "a.png", "boxes": [[0, 0, 1, NaN]], "classes": ["yield"]}', "four finite numbers"),
    ('{"image": "a.png", "boxes": [[0, 0, 0, 1]], "classes": ["yield"]}', "x0 < x1"),  # no width: nothing to learn
    ('{"image": "a.png", "boxes": [], "classes": [], "meta": "front"}', "field 'meta' is \"front\""),
])
def test_malformed_lines_raise_one_line_errors(tmp_path, line, match):
    (tmp_path / "train.jsonl").write_text('{"image": "a.png", "boxes": [], "classes": []}\n' + line + "\n")
    with pytest.raises(DatasetError, match=re.escape(match)) as info:
        SignDataset(tmp_path, "train")
    assert isinstance(info.value, AvsimError) and "\n" not in str(info.value)
    assert "train.jsonl:2" in str(info.value)  # the file and line to fix


def _png(root: Path, rel: str) -> Path:
    (root / rel).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(root / rel), np.zeros((64, 64, 3), np.uint8))
    return root / rel


def test_missing_split_and_missing_image(tmp_path):
    with pytest.raises(DatasetError, match="train.jsonl is missing"):
        SignDataset(tmp_path, "train")
    _png(tmp_path, "a.png")
    (tmp_path / "train.jsonl").write_text('{"image": "a.png", "boxes": [], "classes": []}\n'
                                          '{"image": "gone.png", "boxes": [], "classes": []}\n')
    # Refused when the dataset is read, not when an epoch reaches the image.
    with pytest.raises(DatasetError, match=r"train.jsonl:2: image .*gone.png does not exist"):
        SignDataset(tmp_path, "train")


@pytest.mark.parametrize("damage, match", [
    (lambda path: path.write_bytes(b""), "is empty"),
    (lambda path: path.write_bytes(path.read_bytes()[:-20]), "is cut short"),
    (lambda path: (path.unlink(), path.mkdir()), "is a folder, not a regular file"),
])
def test_damaged_images_are_refused_before_any_is_read(tmp_path, damage, match):
    for name in ("a.png", "b.png"):
        _png(tmp_path, f"images/{name}")
    (tmp_path / "val.jsonl").write_text("".join(json.dumps({"image": f"images/{name}", "boxes": [], "classes": []}) + "\n"
                                                for name in ("a.png", "b.png")))
    assert len(SignDataset(tmp_path, "val")) == 2  # complete PNGs pass
    damage(tmp_path / "images/b.png")
    with pytest.raises(DatasetError, match=f"val.jsonl:2: image .*b.png {match}") as info:
        SignDataset(tmp_path, "val")
    assert "\n" not in str(info.value)
