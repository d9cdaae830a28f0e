"""`avsim detect`: a pixel perception run on image files, one JSON-ready record per image."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from avsim.config import PerceptionConfig
from avsim.image_files import ImageError, check_image_file, decode_image
from avsim.perception.factory import build_frame_detector


def _check_readable(paths: list[Path]) -> None:
    """Every file decodes, or a one-line ImageError before the first record is printed. Each image is decoded
    here and again for its turn, not kept: the second decode costs little beside the network, and a long list
    of photos held at once could fill the memory."""
    for path in paths:
        check_image_file(path)  # a folder, a missing file, a decompression bomb: one line
        if not cv2.haveImageReader(str(path)):
            raise ImageError(f"{path} is not an image OpenCV can read; pass PNG, JPEG or another common format")
        read_rgb(path)  # a file cut short or corrupt past its header


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an image file (grey and alpha images are converted)."""
    image = decode_image(check_image_file(path), path, cv2.IMREAD_COLOR)
    return np.ascontiguousarray(image[..., ::-1])


def detect_images(config: PerceptionConfig, paths: list[Path]) -> Iterator[dict[str, Any]]:
    """One record per image: {"image", "width", "height", "perception", "detections": [...]}.

    Every file is checked before the network is built; each detection is
    {"class", "confidence", "box_xyxy_px"} in the image's own pixels, highest confidence first,
    with "source" (the network that reported it) from a perception that runs several (`ensemble`).
    """
    _check_readable(paths)
    detector = build_frame_detector(config)
    for path in paths:
        image = read_rgb(path)
        detections = detector.detect(image, "image", region_px=None)
        yield {
            "image": str(path),
            "width": int(image.shape[1]),
            "height": int(image.shape[0]),
            "perception": config.kind,
            "detections": [{"class": d.class_name, "confidence": round(d.confidence, 6),
                            "box_xyxy_px": [round(v, 3) for v in d.box_xyxy_px], **({"source": d.source} if d.source else {})}
                           for d in detections],
        }
