"""`avsim detector make-data --format coco|yolo`: the same labels as the JSON lines, read back by
pycocotools (ground truth scored against itself gives AP 1) and by a YOLO label parser."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from avsim.cli import main
from avsim.errors import ConfigError
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.datagen import DataGenConfig, make_dataset

# Seed 5 puts signs, stop signs among them, in both splits (checked below: a change that empties one fails loudly).
TINY = dict(n_train=4, n_val=2, images_per_scene=4, seed=5, workers=1)
IMAGE_META_KEYS = {"town", "placement", "dist_m", "sun_elevation_deg", "sun_azimuth_deg", "sun_intensity", "fog_start_m",
                   "fog_end_m", "camera"}


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    root = tmp_path_factory.mktemp("formats")
    jsonl = make_dataset(root / "jsonl", DataGenConfig(**TINY))
    coco = make_dataset(root / "coco", DataGenConfig(**TINY, label_format="coco"))
    yolo = root / "yolo"
    argv = ["detector", "make-data", "--out", str(yolo), "--format", "yolo", "--train", "4", "--val", "2",
            "--images-per-scene", "4", "--seed", "5", "--workers", "1"]
    assert main(argv) == 0
    records = {split: [json.loads(line) for line in (jsonl / f"{split}.jsonl").read_text().splitlines()] for split in ("train", "val")}
    assert all(any(r["boxes"] for r in records[split]) for split in records), "no sign in a split: pick another seed"
    assert any("stop_sign" in r["classes"] for split in records for r in records[split])
    return records, jsonl, coco, yolo


def test_coco_holds_the_same_boxes_and_the_metadata_of_each_image(datasets):
    records, jsonl, coco_root, _ = datasets
    for split, split_records in records.items():
        assert not (coco_root / f"{split}.jsonl").exists()
        coco = json.loads((coco_root / "annotations" / f"instances_{split}.json").read_text())
        assert [c["name"] for c in sorted(coco["categories"], key=lambda c: c["id"])] == list(SIGN_CLASSES)
        names = {c["id"]: c["name"] for c in coco["categories"]}
        assert len(coco["images"]) == len(split_records)
        for image, record in zip(coco["images"], split_records):
            assert (image["width"], image["height"]) == (640, 480)
            assert IMAGE_META_KEYS <= image.keys() and image["town"] == record["meta"]["town"]
            # Same render, same bytes, found from the image root images/<split>/.
            assert (coco_root / "images" / split / image["file_name"]).read_bytes() == (jsonl / record["image"]).read_bytes()
            boxes = [a for a in coco["annotations"] if a["image_id"] == image["id"]]
            assert [names[a["category_id"]] for a in boxes] == record["classes"]
            for annotation, (x0, y0, x1, y1) in zip(boxes, record["boxes"]):
                x, y, w, h = annotation["bbox"]
                assert (x, y) == (x0, y0) and (x + w, y + h) == pytest.approx((x1, y1), abs=2e-3)
                assert annotation["iscrowd"] == 0 and annotation["area"] == pytest.approx(w * h, abs=1e-2)


def test_pycocotools_scores_the_ground_truth_against_itself_at_ap_1(datasets, capsys):
    _, _, coco_root, _ = datasets
    for split in ("train", "val"):
        truth = COCO(str(coco_root / "annotations" / f"instances_{split}.json"))
        detections = truth.loadRes([{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 1.0}
                                    for a in truth.dataset["annotations"]])
        evaluation = COCOeval(truth, detections, "bbox")
        evaluation.evaluate()
        evaluation.accumulate()
        evaluation.summarize()
        assert evaluation.stats[0] == pytest.approx(1.0)  # AP at IoU 0.50:0.95
        assert evaluation.stats[1] == pytest.approx(1.0)  # AP at IoU 0.50
    capsys.readouterr()


def _parse_yolo_label(path: Path) -> list[tuple[int, float, float, float, float]]:
    rows = []
    for line in path.read_text().splitlines():
        fields = line.split()
        assert len(fields) == 5, line
        cls, values = int(fields[0]), [float(v) for v in fields[1:]]
        assert 0 <= cls < len(SIGN_CLASSES) and all(0.0 <= v <= 1.0 for v in values), line
        rows.append((cls, *values))
    return rows


def test_yolo_has_a_data_yaml_ultralytics_reads_and_one_label_file_per_image(datasets):
    records, _, _, yolo = datasets
    data = yaml.safe_load((yolo / "data.yaml").read_text())
    assert Path(data["path"]) == yolo.resolve()
    assert data["names"] == dict(enumerate(SIGN_CLASSES))
    for split, split_records in records.items():
        images = sorted((Path(data["path"]) / data[split]).glob("*.png"))
        assert [p.name for p in images] == [Path(r["image"]).name for r in split_records]
        for image, record in zip(images, split_records):
            # ultralytics finds a label by replacing /images/ with /labels/ and the suffix with .txt
            label = Path(str(image).replace("/images/", "/labels/")).with_suffix(".txt")
            rows = _parse_yolo_label(label)
            assert [SIGN_CLASSES[r[0]] for r in rows] == record["classes"]
            for (_, cx, cy, w, h), box in zip(rows, record["boxes"]):
                xyxy = np.array([(cx - w / 2) * 640, (cy - h / 2) * 480, (cx + w / 2) * 640, (cy + h / 2) * 480])
                assert xyxy == pytest.approx(box, abs=2e-3)


def test_an_unknown_format_is_refused():
    with pytest.raises(ConfigError, match="--format must be one of jsonl, coco, yolo"):
        DataGenConfig(label_format="voc")
