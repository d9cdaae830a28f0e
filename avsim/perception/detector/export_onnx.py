"""`avsim detector export --format onnx`: the sign detector in the YOLOv8/YOLO11 output layout.

The exported graph takes what an Ultralytics export takes, (1, 3, H, W) RGB in [0, 1]
letterboxed into H x W (grey 114 padding), and returns (1, 4 + C, N):
  rows 0-3     cx, cy, w, h of each cell's box [input px]
  rows 4..4+C  per-class scores, sigmoid(objectness) * sigmoid(class logit)
over the N cells of both strides. So `--perception onnx` runs it exactly as it runs a
user's YOLO export, and the round trip (`tests/perception/detector/test_export_onnx.py`) checks that layout
against the PyTorch detector. H x W is the detector's deployed 480 x 640 by default.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import torch
from torch import nn

from avsim.errors import AvsimError
from avsim.perception.detector.boxes import MAX_LOG_SIZE, cell_centres
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE, SignDetector
from avsim.perception.detector.weights import load_weights

OPSET = 17
INPUT_NAME = "images"
OUTPUT_NAME = "output0"  # the name Ultralytics exports use


class YoloLayout(nn.Module):
    """A fused SignDetector with its decoding, for input_size (W_in, H_in): (1, 3, H, W) -> (1, 4 + C, N)."""

    def __init__(self, detector: SignDetector, input_size: tuple[int, int]) -> None:
        super().__init__()
        self.detector = detector
        width, height = input_size
        centres, strides = [], []
        for stride in detector.strides:
            centres.append(cell_centres(height // stride, width // stride, stride))
            strides.append(torch.full((centres[-1].shape[0],), float(stride)))
        self.register_buffer("centres", torch.cat(centres).T.unsqueeze(0))  # (1, 2, N)
        self.register_buffer("strides", torch.cat(strides).reshape(1, 1, -1))  # (1, 1, N)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """(1, 3, H_in, W_in) RGB in [0, 1] -> (1, 4 + C, N): per cell cx, cy, w, h [input px] and the C
        class scores (objectness x class probability), N cells over both strides.
        """
        preds = torch.cat([out.flatten(2) for out in self.detector(images)], dim=2)  # (B, 1 + C + 4, N)
        num_classes = self.detector.num_classes
        raw = preds[:, 1 + num_classes:]
        centre = self.centres + raw[:, :2] * self.strides
        size = torch.exp(raw[:, 2:].clamp(max=MAX_LOG_SIZE)) * self.strides
        scores = torch.sigmoid(preds[:, :1]) * torch.sigmoid(preds[:, 1:1 + num_classes])
        return torch.cat([centre, size, scores], dim=1)


def export_onnx(weights_path: str | Path, out_path: str | Path, input_size: tuple[int, int] = DEPLOY_INPUT_SIZE) -> Path:
    """Write the detector at `weights_path` as ONNX (opset 17) to `out_path`, atomically.

    The file's metadata holds the class names ("names", as Ultralytics writes them).
    Raises WeightsError for unusable weights, AvsimError if the `onnx` extra is missing.
    """
    try:
        import onnx
    except ImportError:
        raise AvsimError("exporting to ONNX needs the onnx extra: pip install -e '.[onnx]'") from None
    model, meta = load_weights(weights_path)
    wrapper = YoloLayout(model.fuse(), input_size).eval()
    width, height = input_size
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(f".{out_path.name}.tmp-{os.getpid()}")
    try:
        with warnings.catch_warnings():
            # The TorchScript exporter is deprecated in favour of torch.export's, which needs onnxscript.
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.onnx.export(wrapper, (torch.zeros(1, 3, height, width),), str(tmp), dynamo=False, opset_version=OPSET,
                              input_names=[INPUT_NAME], output_names=[OUTPUT_NAME])
        proto = onnx.load(str(tmp))
        names = {i: name for i, name in enumerate(meta["class_names"])}
        onnx.helper.set_model_props(proto, {"names": repr(names), "author": "avsim detector export"})
        onnx.save(proto, str(tmp))
        os.replace(tmp, out_path)
    finally:
        tmp.unlink(missing_ok=True)
    return out_path
