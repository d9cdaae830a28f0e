"""Small Darknet cfg/weights files for the reader's tests, written from scratch."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# A YOLOv4-tiny-shaped cfg in miniature: grouped routes, a shortcut, a stride-1 maxpool, two heads.
TINY_CFG = """
[net]
width=64
height=64
channels=3

[convolutional]
batch_normalize=1
filters=8
size=3
stride=2
pad=1
activation=leaky

[convolutional]
batch_normalize=1
filters=8
size=3
stride=1
pad=1
activation=mish

[route]
layers=-1
groups=2
group_id=1

[convolutional]
filters=4
size=1
stride=1
pad=1
activation=leaky

[shortcut]
from=-2
activation=linear

[maxpool]
size=2
stride=2

[maxpool]
size=2
stride=1

[convolutional]
size=1
stride=1
pad=1
filters=21
activation=linear

[yolo]
mask = 1,2,3
anchors = 4,5, 8,9, 16,12, 30,28
classes=2
num=4
scale_x_y = 1.05

[route]
layers = -3

[upsample]
stride=2

[route]
layers = -1, -10

[convolutional]
size=1
stride=1
pad=1
filters=14
activation=linear

[yolo]
mask = 0,1
anchors = 4,5, 8,9, 16,12, 30,28
classes=2
num=4
"""


def write_weights(path: Path, network, rng: np.random.Generator, version: tuple[int, int, int] = (0, 2, 0),
                  extra_floats: int = 0) -> list[dict[str, np.ndarray]]:
    """Random Darknet weights for every conv of `network`, in file layout; returns each conv's arrays."""
    from avsim.perception.yolo.layers import Convolutional

    major, minor, revision = version
    header = np.array([major, minor, revision], "<i4").tobytes()
    header += np.array([12345], "<u8" if major * 10 + minor >= 2 else "<u4").tobytes()
    arrays, chunks = [], []
    for layer in network.layers:
        if not isinstance(layer, Convolutional):
            continue
        n = layer.conv.out_channels
        record = {"bias": rng.normal(0, 0.5, n)}
        if layer.batch_normalize:
            record |= {"scale": rng.uniform(0.5, 1.5, n), "mean": rng.normal(0, 0.2, n), "var": rng.uniform(0.1, 2.0, n)}
        record["kernel"] = rng.normal(0, 0.3, tuple(layer.conv.weight.shape))
        record = {k: v.astype(np.float32) for k, v in record.items()}
        arrays.append(record)
        chunks += [record[k].ravel() for k in ("bias", "scale", "mean", "var", "kernel") if k in record]
    chunks.append(np.zeros(extra_floats, np.float32))
    path.write_bytes(header + np.concatenate(chunks).astype("<f4").tobytes())
    return arrays
