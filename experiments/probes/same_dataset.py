"""One-off probe: are two detector datasets the same, label for label and pixel for pixel?

Made to answer whether `avsim detector make-data` still draws the data the shipped weights were trained on
(commit 1649ab9, 2026-11-22): make the dataset with that commit's code and with today's, then compare them:

    git worktree add /tmp/avsim-1649ab9 1649ab9
    PYTHONPATH=/tmp/avsim-1649ab9 MUJOCO_GL=egl python -m avsim detector make-data --out /tmp/signs_1649ab9
    MUJOCO_GL=egl python -m avsim detector make-data --out data/signs
    python experiments/probes/same_dataset.py data/signs /tmp/signs_1649ab9

For each split it prints how many labels lines differ in their boxes, classes or view (the `meta` keys both
lines have; newer datasets record more of them) and how many images differ in any pixel, by town. Files that are
byte-identical are not decoded. It is not part of avsim; it writes nothing. 5 s for 7,000 identical images, about a
minute when every image must be decoded.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import cv2
import numpy as np


def labels(dataset: Path, split: str) -> list[dict]:
    """The labels lines of `dataset/split.jsonl`, in order."""
    with (dataset / f"{split}.jsonl").open(encoding="utf-8") as lines:
        return [json.loads(line) for line in lines if line.strip()]


def same_view(a: dict, b: dict) -> bool:
    """Whether two labels lines give the same boxes, classes and view (the meta keys both have)."""
    shared = a.get("meta", {}).keys() & b.get("meta", {}).keys()
    return (a["boxes"] == b["boxes"] and a["classes"] == b["classes"]
            and all(a["meta"][key] == b["meta"][key] for key in shared))


def same_pixels(path_a: Path, path_b: Path) -> bool:
    """Whether two image files hold the same pixels (byte-identical files are not decoded)."""
    if path_a.read_bytes() == path_b.read_bytes():
        return True
    image_a, image_b = cv2.imread(str(path_a), cv2.IMREAD_UNCHANGED), cv2.imread(str(path_b), cv2.IMREAD_UNCHANGED)
    return image_a is not None and image_b is not None and image_a.shape == image_b.shape and bool(np.array_equal(image_a, image_b))


def compare(dataset_a: Path, dataset_b: Path, split: str) -> bool:
    """Print one split's differences; True when there are none."""
    lines_a, lines_b = labels(dataset_a, split), labels(dataset_b, split)
    if len(lines_a) != len(lines_b):
        print(f"{split}: {len(lines_a)} against {len(lines_b)} images")
        return False
    views_differ = sum(not same_view(a, b) for a, b in zip(lines_a, lines_b))
    per_town, pixels_differ = Counter(), Counter()
    for a, b in zip(lines_a, lines_b):
        town = a.get("meta", {}).get("town", "?")
        per_town[town] += 1
        if not same_pixels(dataset_a / a["image"], dataset_b / b["image"]):
            pixels_differ[town] += 1
    towns = ", ".join(f"{town} {pixels_differ[town]} of {n}" for town, n in sorted(per_town.items()))
    print(f"{split}: {len(lines_a)} images; labels lines that differ: {views_differ}; images that differ: {towns}")
    return views_differ == 0 and not pixels_differ


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset_a", type=Path)
    parser.add_argument("dataset_b", type=Path)
    args = parser.parse_args()
    same = [compare(args.dataset_a, args.dataset_b, split) for split in ("train", "val")]
    print("the same" if all(same) else "they differ")
    return 0 if all(same) else 1


if __name__ == "__main__":
    sys.exit(main())
