"""A Darknet YOLO loaded from its three files: pixels (0-255) -> per-class scores, and detections.

`load_yolo()` reads the fetched YOLOv3-tiny (`fetch.model_paths()`); `load_yolo(cfg, weights,
names)` reads a user's own YOLOv3/v4-tiny style files (`perception.yolo_cfg`, `.yolo_weights`,
`.yolo_names`).
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from avsim.perception.yolo import fetch
from avsim.perception.yolo.cfg import DarknetFileError, parse_cfg
from avsim.perception.yolo.decode import DecodedBoxes, decode_heads, score_rows
from avsim.perception.yolo.network import DarknetNetwork
from avsim.perception.yolo.weights import load_weights

PIXEL_SCALE = 1.0 / 255.0  # Darknet's input is RGB in 0..1


def read_names(path: str | Path) -> tuple[str, ...]:
    """Class names, one a line (blank lines skipped), index = class id."""
    path = Path(path)
    try:
        names = tuple(line.strip() for line in path.read_text(encoding="utf-8").splitlines() if line.strip())
    except FileNotFoundError:
        raise DarknetFileError(f"Darknet names file {path} does not exist; check perception.yolo_names") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DarknetFileError(f"Darknet names file {path} cannot be read as text ({exc}); check perception.yolo_names") from None
    return names


class YoloModel(nn.Module):
    """A Darknet network with its `[yolo]` decoding.

    class_names: index = class id; the name "stop sign" (COCO's) is reported as avsim's `stop_sign`.
    """

    def __init__(self, network: DarknetNetwork, class_names: tuple[str, ...]) -> None:
        super().__init__()
        classes = {head.classes for head in network.heads}
        if classes != {len(class_names)}:
            raise DarknetFileError(f"the cfg's [yolo] layers have {sorted(classes)} classes but the names file lists "
                                   f"{len(class_names)}; give the names file that belongs to the weights")
        self.network = network.eval().to(memory_format=torch.channels_last)  # as the inputs (`preprocess`)
        self.class_names = class_names

    @property
    def input_size_px(self) -> tuple[int, int]:
        """(width, height) of the cfg's [net]: the size the network was trained at."""
        return self.network.input_size_px

    @property
    def size_multiple_px(self) -> int:
        """What the input's width and height must be multiples of [px] (the network's largest downsampling)."""
        return self.network.size_multiple_px

    def decoded(self, images: torch.Tensor) -> DecodedBoxes:
        """(B, 3, H, W) float RGB 0-255 -> every head's boxes [input px], objectness and class probabilities.

        H and W must be multiples of `size_multiple_px`. Differentiable in `images`.
        """
        return decode_heads(self.network(images * PIXEL_SCALE), self.network.heads, tuple(images.shape[-2:]))

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, 3, H, W) 0-255 -> (boxes (B, N, 4) [input px], class scores (B, N, C)) before any NMS."""
        decoded = self.decoded(images)
        return decoded.boxes_xyxy, decoded.class_scores()

    def detect(self, images: torch.Tensor, min_score: float) -> torch.Tensor:
        """(1, 3, H, W) -> (1, n, 6) float32: x1, y1, x2, y2 [input px], score, class of every
        (box, class) scoring at least `min_score`, highest first; no NMS."""
        return score_rows(self.decoded(images), min_score)[None]


def load_yolo(cfg_path: str | Path | None = None, weights_path: str | Path | None = None,
              names_path: str | Path | None = None) -> YoloModel:
    """The model from Darknet files; each None is the fetched YOLOv3-tiny's (sha256-checked)."""
    if cfg_path is None or weights_path is None or names_path is None:
        fetched = fetch.model_paths()
        cfg_path = fetched[0] if cfg_path is None else cfg_path
        weights_path = fetched[1] if weights_path is None else weights_path
        names_path = fetched[2] if names_path is None else names_path
    network = DarknetNetwork(parse_cfg(cfg_path))
    load_weights(network, weights_path)
    return YoloModel(network, read_names(names_path))
