"""`--perception onnx`: a user's YOLOv8/YOLO11-layout ONNX detector, run with onnxruntime.

The model must have one image input (1, 3, H, W), RGB in [0, 1], and an output (1, 4 + C, N):
cx, cy, w, h [input px] and C class scores per candidate, as Ultralytics exports write it.
Per frame: letterbox into H x W (aspect kept, grey 114 padding; a 640x480 frame into a
640x480 model is the identity) -> the model -> per candidate the best class and its score
-> candidates above `min_confidence` (at most 1000, best first) -> class-aware NMS (IoU 0.5)
-> at most 100 boxes, mapped back to image pixels and clipped. With a region of interest,
only boxes centred inside it are reported (the model still sees the whole frame). A model
with dynamic H or W gets 640 x 640, the Ultralytics default.

`perception.onnx_classes` names the class ids (index = id); the policies act on "stop_sign".
A file onnxruntime cannot load, or whose input or output does not have this layout, is one
line naming the problem (exit 2) when the perception is built.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from avsim.errors import AvsimError
from avsim.perception.base import Detection, touches_border
from avsim.perception.detector.letterbox import check_image, fit, to_tensor, warp
from avsim.perception.detector.postprocess import IOU_THRESHOLD, MAX_DETECTIONS, PRE_NMS_TOP_K, nms

DYNAMIC_INPUT_SIZE = (640, 640)  # (W, H), Ultralytics' default image size
Region = tuple[int, int, int, int]


class OnnxModelError(AvsimError):
    """An ONNX file that is missing, unreadable, or not in the YOLO output layout."""


def _static(dim: object) -> int | None:
    return dim if isinstance(dim, int) and dim > 0 else None


class OnnxRunner:
    """`detect(image, camera, region_px)`: the model's boxes in one frame, highest confidence first."""

    def __init__(self, path: str | Path, class_names: tuple[str, ...], min_confidence: float, threads: int = 1) -> None:
        path = Path(path)
        if path.is_dir():
            raise OnnxModelError(f"ONNX model {path} is a folder; set perception.onnx_path to the .onnx file in it")
        if not path.is_file():
            raise OnnxModelError(f"ONNX model {path} does not exist; set perception.onnx_path to a .onnx file")
        try:
            import onnxruntime as ort
        except ImportError:
            raise OnnxModelError("--perception onnx needs onnxruntime: pip install -e '.[onnx]'") from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.log_severity_level = 3  # errors only: the one-line message below says what went wrong
        try:
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own exception types for every kind of bad file
            reason = " ".join(str(exc).split())[:160]
            raise OnnxModelError(f"ONNX model {path} cannot be loaded by onnxruntime ({reason}); "
                                 "export it again (e.g. YOLO export format=onnx)") from None
        self.path = path
        self.class_names = tuple(class_names)
        self.min_confidence = min_confidence
        self.input_name, self.input_size = self._check_input()
        self._check_output()

    def _check_input(self) -> tuple[str, tuple[int, int]]:
        inputs = self.session.get_inputs()
        if len(inputs) != 1 or len(inputs[0].shape) != 4 or inputs[0].shape[1] != 3:
            shapes = [list(i.shape) for i in inputs]
            raise OnnxModelError(f"ONNX model {self.path} must take one (1, 3, H, W) image, it takes {shapes}; "
                                 "export a YOLOv8/YOLO11-layout detector")
        height, width = _static(inputs[0].shape[2]), _static(inputs[0].shape[3])
        size = (width, height) if width and height else DYNAMIC_INPUT_SIZE
        return inputs[0].name, size

    def _check_output(self, shape: tuple[int, ...] | None = None) -> None:
        dims = shape if shape is not None else tuple(self.session.get_outputs()[0].shape)
        rows = dims[1] if len(dims) == 3 else None
        if len(dims) != 3 or (isinstance(rows, int) and rows != 4 + len(self.class_names)):
            raise OnnxModelError(f"ONNX model {self.path} outputs {list(dims)}, expected [1, 4 + C, N] with "
                                 f"C = {len(self.class_names)} classes from perception.onnx_classes")

    def raw_output(self, image_rgb: np.ndarray) -> tuple[np.ndarray, object]:
        """((4 + C, N) model output, the Letterbox) for one (H, W, 3) uint8 RGB image."""
        check_image(image_rgb)
        box = fit(image_rgb.shape[1], image_rgb.shape[0], self.input_size)
        tensor = to_tensor(warp(image_rgb, box)).unsqueeze(0).contiguous().numpy()
        output = self.session.run(None, {self.input_name: tensor})[0]
        self._check_output(output.shape)
        return output[0], box

    def detect(self, image_rgb: np.ndarray, camera: str, region_px: Region | None = None) -> list[Detection]:
        """Detections in one (H, W, 3) uint8 RGB image; boxes in image pixels, clipped to it."""
        image_h, image_w = image_rgb.shape[:2]
        output, box = self.raw_output(image_rgb)
        class_scores = output[4:]
        classes = class_scores.argmax(axis=0)
        scores = class_scores[classes, np.arange(class_scores.shape[1])]
        cells = np.flatnonzero(scores > self.min_confidence)
        cells = cells[np.argsort(-scores[cells], kind="stable")][:PRE_NMS_TOP_K]
        cx, cy, w, h = output[:4, cells]
        half_w, half_h = 0.5 * w, 0.5 * h
        boxes_in = np.stack([cx - half_w, cy - half_h, cx + half_w, cy + half_h], axis=1)  # input px
        scores, classes = scores[cells], classes[cells]
        if region_px is not None:
            centres = box.to_image(boxes_in)
            mid_x, mid_y = (centres[:, 0] + centres[:, 2]) / 2, (centres[:, 1] + centres[:, 3]) / 2
            x0, y0, x1, y1 = region_px
            inside = (mid_x >= x0) & (mid_x < x1) & (mid_y >= y0) & (mid_y < y1)
            boxes_in, scores, classes = boxes_in[inside], scores[inside], classes[inside]
        # NMS on the unclipped input-pixel boxes, then map and clip, as the `detector` perception does.
        keep = nms(boxes_in, scores, classes, IOU_THRESHOLD)[:MAX_DETECTIONS]
        boxes = np.clip(box.to_image(boxes_in[keep]), 0.0, [image_w, image_h, image_w, image_h])
        scores, classes = scores[keep], classes[keep]
        detections = []
        for (x0, y0, x1, y1), score, cls in zip(boxes, scores, classes):
            xyxy = (float(x0), float(y0), float(x1), float(y1))
            detections.append(Detection(self.class_names[int(cls)], float(score), xyxy, camera,
                                        touches_border(xyxy, image_w, image_h)))
        return detections
