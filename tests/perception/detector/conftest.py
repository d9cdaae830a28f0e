"""A tiny synthetic sign dataset in the detector's JSONL format, drawn with OpenCV.

640x480 frames: a noisy sky/grass background with a grey road; 0-2 signs per frame,
15-80 px tall: red octagons with a white text blob (stop_sign), inverted white triangles
with a red border (yield), white rectangles with a black border and black text
(speed_limit). About one frame in five has no sign.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

WIDTH, HEIGHT = 640, 480
SHIFT = 4  # fixed-point bits for sub-pixel polygon vertices


def _background(rng: np.random.Generator) -> np.ndarray:
    image = np.empty((HEIGHT, WIDTH, 3), np.float32)
    horizon = int(rng.integers(200, 260))
    image[:horizon] = rng.uniform(150, 220, 3)
    image[horizon:] = (rng.uniform(40, 90), rng.uniform(90, 140), rng.uniform(30, 70))
    cv2.fillPoly(image, [np.array([[250, horizon], [390, horizon], [640, 480], [0, 480]], np.int32)], (90, 90, 92))
    image += rng.normal(0.0, rng.uniform(3, 12), image.shape).astype(np.float32)
    return np.clip(image, 0, 255).astype(np.uint8)


def _poly(image: np.ndarray, points: np.ndarray, colour: tuple[int, int, int]) -> None:
    cv2.fillPoly(image, [np.round(points * (1 << SHIFT)).astype(np.int32)], colour, cv2.LINE_AA, SHIFT)


def _draw_sign(image: np.ndarray, kind: str, cx: float, cy: float, size: float) -> list[float]:
    """Draw one sign of height `size` [px] centred at (cx, cy); returns its box xyxy."""
    half = size / 2
    if kind == "stop_sign":
        angles = np.deg2rad(22.5 + 45.0 * np.arange(8))
        r = half / np.cos(np.deg2rad(22.5))
        pts = np.stack([cx + r * np.cos(angles), cy + r * np.sin(angles)], axis=1)
        _poly(image, pts, (200, 25, 30))
        _poly(image, np.array([[cx - 0.6 * half, cy - 0.2 * half], [cx + 0.6 * half, cy - 0.2 * half],
                               [cx + 0.6 * half, cy + 0.2 * half], [cx - 0.6 * half, cy + 0.2 * half]]), (240, 240, 240))
        return [float(cx - half), float(cy - half), float(cx + half), float(cy + half)]
    if kind == "yield":
        w = size * 1.15
        outer = np.array([[cx - w / 2, cy - half], [cx + w / 2, cy - half], [cx, cy + half]])
        inner = cx + (outer[:, 0] - cx) * 0.6, cy - half * 0.1 + (outer[:, 1] - cy) * 0.6
        _poly(image, outer, (210, 30, 35))
        _poly(image, np.stack(inner, axis=1), (245, 245, 245))
        return [float(cx - w / 2), float(cy - half), float(cx + w / 2), float(cy + half)]
    w = size * 0.8
    _poly(image, np.array([[cx - w / 2, cy - half], [cx + w / 2, cy - half], [cx + w / 2, cy + half], [cx - w / 2, cy + half]]), (20, 20, 20))
    b = max(1.0, 0.08 * size)
    _poly(image, np.array([[cx - w / 2 + b, cy - half + b], [cx + w / 2 - b, cy - half + b],
                           [cx + w / 2 - b, cy + half - b], [cx - w / 2 + b, cy + half - b]]), (245, 245, 245))
    _poly(image, np.array([[cx - w / 4, cy], [cx + w / 4, cy], [cx + w / 4, cy + half / 2], [cx - w / 4, cy + half / 2]]), (15, 15, 15))
    return [float(cx - w / 2), float(cy - half), float(cx + w / 2), float(cy + half)]


def make_synthetic_dataset(root: Path, n_train: int = 36, n_val: int = 12, seed: int = 0) -> Path:
    """Write root/{train,val}.jsonl and root/images/{train,val}/*.png; returns root."""
    rng = np.random.default_rng(seed)
    kinds = ("stop_sign", "yield", "speed_limit")
    for split, count in (("train", n_train), ("val", n_val)):
        (root / "images" / split).mkdir(parents=True, exist_ok=True)
        lines = []
        for i in range(count):
            image = _background(rng)
            n_signs = 0 if rng.random() < 0.2 else int(rng.integers(1, 3))
            boxes, classes = [], []
            for k in range(n_signs):
                kind = kinds[int(rng.integers(0, 3))]
                size = float(rng.uniform(15, 80))
                cx = float(rng.uniform(60, 580)) if k == 0 else (float(rng.uniform(60, 280)) if boxes[0][0] > 320 else float(rng.uniform(360, 580)))
                cy = float(rng.uniform(60, 300))
                boxes.append(_draw_sign(image, kind, cx, cy, size))
                classes.append(kind)
            rel = f"images/{split}/{i:06d}.png"
            cv2.imwrite(str(root / rel), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
            lines.append(json.dumps({"image": rel, "boxes": boxes, "classes": classes, "meta": {"dist_m": 30.0}}))
        (root / f"{split}.jsonl").write_text("\n".join(lines) + "\n")
    return root


@pytest.fixture(scope="session")
def synthetic_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_synthetic_dataset(tmp_path_factory.mktemp("signs"))
