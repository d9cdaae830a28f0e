"""The label files of `avsim detector make-data`, in avsim's own format or the ones other tools read.

Every format shares the rendered images, `images/{train,val}/NNNNNN.png`, and `generation.json`.
The labels (boxes in pixels, x0 y0 x1 y1, from segmentation) are written as:

- `jsonl` (the default, read by `avsim detector train` and `eval`): `{train,val}.jsonl`, one
  record per image, {"image", "boxes": [[x0, y0, x1, y1]], "classes", "meta"}.
- `coco`: `annotations/instances_{train,val}.json` in the COCO detection format. Categories
  1 stop_sign, 2 yield, 3 speed_limit; `bbox` is [x, y, width, height] in pixels; an image's
  `file_name` is relative to `images/<split>/` (the image root a COCO loader is given). Each image
  entry also carries the render's metadata: town, placement, layout_seed, camera,
  target_kind (the sign at the stop line), dist_m (camera to that sign along the road [m]; -1
  when the camera was not looking down the road at it), sun_elevation_deg, sun_azimuth_deg,
  sun_intensity, fog_start_m and fog_end_m (0: no fog).
- `yolo`: `labels/{train,val}/NNNNNN.txt` beside `images/`, one line per box "class cx cy w h"
  with class 0 stop_sign, 1 yield, 2 speed_limit and the box normalised by the image size (an
  image without signs has an empty file), and `data.yaml` (path, train, val, names) as the
  ultralytics YOLOv8/YOLO11 trainers read it: `yolo detect train data=DIR/data.yaml`. Its
  `path` is the dataset's absolute path, so a moved dataset needs that line changed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

from avsim import __version__
from avsim.outputs import write_text
from avsim.perception.base import SIGN_CLASSES

FORMATS = ("jsonl", "coco", "yolo")
SPLITS = ("train", "val")
COCO_CATEGORY_IDS = {name: i + 1 for i, name in enumerate(SIGN_CLASSES)}  # COCO ids start at 1
YOLO_CLASS_IDS = {name: i for i, name in enumerate(SIGN_CLASSES)}


def write_labels(root: Path, label_format: str, records: Mapping[str, Sequence[dict]], image_size_px: tuple[int, int],
                 final_root: Path) -> None:
    """Write `records` (per split, the JSON-lines records) into `root` in `label_format`.

    root: the folder being written (renamed to `final_root` when complete, so files are written
    in place); image_size_px: (width, height) of every image.
    """
    if label_format == "jsonl":
        for split in SPLITS:
            write_text(root / f"{split}.jsonl", "".join(json.dumps(r) + "\n" for r in records[split]), atomic=False)
    elif label_format == "coco":
        for split in SPLITS:
            coco = coco_dataset(records[split], image_size_px)
            write_text(root / "annotations" / f"instances_{split}.json", json.dumps(coco), atomic=False)
    elif label_format == "yolo":
        for split in SPLITS:
            for record in records[split]:
                label = root / "labels" / split / (Path(record["image"]).stem + ".txt")
                write_text(label, yolo_label_text(record, image_size_px), atomic=False)
        write_text(root / "data.yaml", yolo_data_yaml(final_root.resolve()), atomic=False)
    else:
        raise ValueError(f"unknown label format {label_format!r}; one of {FORMATS}")


def coco_dataset(records: Sequence[dict], image_size_px: tuple[int, int]) -> dict:
    """One split as a COCO detection dataset: info, licenses, images, annotations, categories."""
    width, height = image_size_px
    images, annotations = [], []
    for image_id, record in enumerate(records, start=1):
        images.append({"id": image_id, "file_name": Path(record["image"]).name, "width": width, "height": height,
                       **record["meta"]})
        for (x0, y0, x1, y1), name in zip(record["boxes"], record["classes"]):
            box_w, box_h = round(x1 - x0, 3), round(y1 - y0, 3)
            annotations.append({"id": len(annotations) + 1, "image_id": image_id, "category_id": COCO_CATEGORY_IDS[name],
                                "bbox": [x0, y0, box_w, box_h], "area": round(box_w * box_h, 3), "iscrowd": 0})
    return {
        "info": {"description": "avsim sign renders (avsim detector make-data)", "version": __version__},
        "licenses": [],
        "images": images,
        "annotations": annotations,
        "categories": [{"id": i, "name": name, "supercategory": "traffic_sign"} for name, i in COCO_CATEGORY_IDS.items()],
    }


def yolo_label_text(record: dict, image_size_px: tuple[int, int]) -> str:
    """An image's YOLO label file: "class cx cy w h" per box, normalised to [0, 1] by the image size."""
    width, height = image_size_px
    lines = []
    for (x0, y0, x1, y1), name in zip(record["boxes"], record["classes"]):
        lines.append(f"{YOLO_CLASS_IDS[name]} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} "
                     f"{(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}\n")
    return "".join(lines)


def yolo_data_yaml(dataset_path: Path) -> str:
    """The ultralytics dataset file: root `path`, the image folders (labels are found beside them) and class names."""
    # A JSON string is a YAML double-quoted scalar: any path (spaces, colons, '#') reads back exactly.
    names = "".join(f"  {i}: {name}\n" for name, i in YOLO_CLASS_IDS.items())
    return (f"# avsim sign renders (avsim detector make-data --format yolo)\n"
            f"path: {json.dumps(str(dataset_path))}\ntrain: images/train\nval: images/val\nnames:\n{names}")
