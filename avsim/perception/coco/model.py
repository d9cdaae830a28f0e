"""The COCO CenterNet: network and decoding, loaded from the fetched TF.js files.

`CocoCenterNet` is the whole graph in PyTorch:
- `forward(images)` / `maps(images)`: (B, 3, H, W) RGB 0-255 -> heatmap (B, 80, H/4, W/4)
  after the sigmoid, before peak extraction, and wh (B, 4, H/4, W/4) [input px];
  differentiable from the pixels, for attacks;
- `detect(images)`: (B, k, 6) exactly as the graph's `tower_0/detections`: x1, y1, x2, y2 in
  input pixels, score, class (0-based COCO-80, 11 = stop sign).
The graph was exported for 1 x 512 x 512 x 3; both methods take any H, W that are multiples
of 32 (the network is fully convolutional and the decoding reads the map sizes).
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from avsim.perception.coco.decode import DecodeSpec, decode_detections
from avsim.perception.coco import fetch
from avsim.perception.coco.graph import read_graph
from avsim.perception.coco.network import CenterNet, dense_node_names

GRAPH_INPUT_SIZE_PX = 512


class CocoCenterNet(nn.Module):
    """The COCO-80 CenterNet of @vladmandic/human (MobileNetV3), read from its TF.js graph: images
    (B, 3, H, W) RGB 0-255 with H and W multiples of 32 in, dense maps at stride 4 or decoded
    detections out; `spec` holds the graph's decoding constants."""

    def __init__(self, network: CenterNet, spec: DecodeSpec) -> None:
        super().__init__()
        self.network = network
        self.spec = spec

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, 3, H, W) RGB 0-255 -> heatmap (B, 80, H/4, W/4) after the sigmoid, wh (B, 4, H/4, W/4) [input px]."""
        return self.network(images)

    def maps(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """images (B, 3, H, W) RGB 0-255 -> (heatmap (B, 80, H/4, W/4), wh (B, 4, H/4, W/4))."""
        return self.network(images)

    def detect(self, images: torch.Tensor, min_score: float | None = None) -> torch.Tensor:
        """images (B, 3, H, W) RGB 0-255 -> (B, k, 6) detections, as `tower_0/detections`.

        min_score: only the rows scoring at least this (batch 1; `decode_detections`).
        """
        heatmap, wh = self.network(images)
        return decode_detections(heatmap, wh, self.spec, min_score)


def load_centernet(cache_dir: Path | None = None) -> CocoCenterNet:
    """The network from the hash-checked files in `cache_dir` (default: `fetch.CACHE_DIR`), in
    eval mode, channels-last.

    Raises CocoWeightsError (naming the fetch command) if the files are absent or altered.
    """
    json_path, _ = fetch.model_paths(cache_dir)
    graph = read_graph(json_path)
    network = CenterNet.from_graph(graph)
    spec = DecodeSpec.from_graph(graph, dense_node_names(graph))
    return CocoCenterNet(network, spec).eval().to(memory_format=torch.channels_last)
