"""Darknet `.weights` files: a header, then every convolution's parameters in layer order.

Layout (little-endian): int32 major, minor, revision; then `seen` (images trained on), an
int64 when major * 10 + minor >= 2 and an int32 before that. Then, for each
`[convolutional]` layer in file order, float32 arrays: biases (n); if the layer has
`batch_normalize=1`, its scales (n), rolling means (n) and rolling variances (n); then the
kernel (n, c / groups, size, size). Nothing else in a YOLO tiny cfg has weights.

Batch norm is folded into the conv as Darknet computes it at inference,
y = scale * (x - mean) / (sqrt(var) + 1e-6) + bias: kernel * k and bias - mean * k with
k = scale / (sqrt(var) + 1e-6).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from avsim.perception.yolo.cfg import DarknetFileError
from avsim.perception.yolo.layers import Convolutional
from avsim.perception.yolo.network import DarknetNetwork

BN_EPS = 1e-6  # Darknet's normalize_cpu adds it to the standard deviation


@dataclass(frozen=True)
class WeightsHeader:
    """The header of a Darknet .weights file: format version (major.minor.revision), the images
    `seen` in training, and the header's own length in bytes (the weights follow it)."""

    major: int
    minor: int
    revision: int
    seen: int
    size_bytes: int  # 20 with an int64 `seen`, 16 with an int32 one


def read_header(data: bytes, source: str) -> WeightsHeader:
    """The header at the start of a .weights file's bytes."""
    if len(data) < 16:
        raise DarknetFileError(f"Darknet weights {source} are {len(data)} bytes, shorter than the header; "
                               "check perception.yolo_weights")
    major, minor, revision = (int(v) for v in np.frombuffer(data, "<i4", 3))
    if major > 1000 or minor > 1000:
        raise DarknetFileError(f"Darknet weights {source} have version {major}.{minor} (transposed layout), "
                               "which avsim does not read")
    if major * 10 + minor >= 2:
        return WeightsHeader(major, minor, revision, int(np.frombuffer(data, "<u8", 1, 12)[0]), 20)
    return WeightsHeader(major, minor, revision, int(np.frombuffer(data, "<u4", 1, 12)[0]), 16)


def _needed_floats(network: DarknetNetwork) -> int:
    total = 0
    for layer in network.layers:
        if isinstance(layer, Convolutional):
            n = layer.conv.out_channels
            total += n * (4 if layer.batch_normalize else 1) + layer.conv.weight.numel()
    return total


def load_weights(network: DarknetNetwork, path: str | Path) -> WeightsHeader:
    """Read `path` into `network`'s convolutions (batch norm folded in); returns its header.

    Raises DarknetFileError if the file does not exist or its size does not fit the cfg.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DarknetFileError(f"Darknet weights {path} do not exist; check perception.yolo_weights") from None
    except OSError as exc:
        raise DarknetFileError(f"Darknet weights {path} cannot be read ({exc}); check perception.yolo_weights") from None
    header = read_header(data, str(path))
    body = len(data) - header.size_bytes
    needed = _needed_floats(network)
    if body != 4 * needed:
        raise DarknetFileError(f"Darknet weights {path} hold {body} bytes after the header, but the cfg's convolutions "
                               f"need {4 * needed} ({needed} float32): the weights are not for this cfg")
    values = np.frombuffer(data, "<f4", needed, header.size_bytes)
    offset = 0

    def take(count: int) -> np.ndarray:
        nonlocal offset
        offset += count
        return values[offset - count:offset].astype(np.float64)

    with torch.no_grad():
        for layer in network.layers:
            if not isinstance(layer, Convolutional):
                continue
            conv = layer.conv
            n = conv.out_channels
            bias = take(n)
            if layer.batch_normalize:
                scale, mean, var = take(n), take(n), take(n)
                k = scale / (np.sqrt(np.maximum(var, 0.0)) + BN_EPS)
                bias = bias - mean * k
            else:
                k = np.ones(n)
            kernel = take(conv.weight.numel()).reshape(conv.weight.shape) * k[:, None, None, None]
            conv.weight.copy_(torch.from_numpy(kernel))
            conv.bias.copy_(torch.from_numpy(bias))
    return header
