"""COCO-80 class names in the order of the CenterNet's heatmap channels (0-based).

The network's class 11 is COCO's "stop sign", which avsim reports as `stop_sign`, the
class its policies act on. Every other class keeps its COCO name and only shows up in the
records: no policy acts on a "traffic light" or a "car".
"""

from __future__ import annotations

COCO_CLASSES = (
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat", "traffic light",
    "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog", "horse", "sheep", "cow",
    "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee",
    "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
    "tennis racket", "bottle", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple",
    "sandwich", "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch",
    "potted plant", "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors", "teddy bear",
    "hair drier", "toothbrush",
)
STOP_SIGN_CLASS_ID = COCO_CLASSES.index("stop sign")  # 11
# avsim's names: the stop sign as the policies know it, the rest as COCO names them.
AVSIM_CLASS_NAMES = tuple("stop_sign" if name == "stop sign" else name for name in COCO_CLASSES)
