"""The detector report's bookkeeping, on a hand-made dataset scored by scripted detectors."""

import json
import re
import shutil

import cv2
import numpy as np
import pytest

from avsim.perception.base import Detection
from avsim.perception.detector.data import DatasetError
from avsim.perception.evaluation import evaluate, write_report

# (boxes, classes, dist_m): two stop signs in different distance bins, a yield, and a sign-free frame.
FRAMES = [
    ([[300, 200, 320, 220]], ["stop_sign"], 40.0),
    ([[300, 150, 360, 210]], ["stop_sign"], 12.0),
    ([[100, 100, 130, 130]], ["yield"], 20.0),
    ([], [], 30.0),
]


@pytest.fixture(scope="module")
def tiny_split(tmp_path_factory):
    root = tmp_path_factory.mktemp("signs")
    (root / "images").mkdir()
    lines = []
    for i, (boxes, classes, dist_m) in enumerate(FRAMES):
        cv2.imwrite(str(root / "images" / f"{i}.png"), np.zeros((480, 640, 3), np.uint8))
        meta = {"camera": "front", "target_kind": "stop_sign" if "stop_sign" in classes else "none", "dist_m": dist_m}
        lines.append(json.dumps({"image": f"images/{i}.png", "boxes": boxes, "classes": classes, "meta": meta}))
    (root / "val.jsonl").write_text("\n".join(lines) + "\n")
    return root


def _replay(frames_detections):
    """A detector that returns scripted detections frame by frame, in dataset order."""
    queue = iter(frames_detections)
    return lambda image, camera: next(queue)


def test_perfect_detections_score_ap_one_full_recall_and_no_false_positives(tiny_split):
    scripted = [[Detection(cls, 0.9, tuple(map(float, box)), "front") for box, cls in zip(boxes, classes)]
                for boxes, classes, _ in FRAMES]
    report = evaluate(_replay(scripted), tiny_split, conf_threshold=0.5, progress=False)
    assert report.ap50["stop_sign"] == pytest.approx(1.0) and report.ap50["yield"] == pytest.approx(1.0)
    assert np.isnan(report.ap50["speed_limit"])
    assert report.recall_by_bin["35-45 m"] == 1.0 and report.recall_by_bin["5-15 m"] == 1.0
    assert report.count_by_bin["35-45 m"] == 1 and report.count_by_bin["15-25 m"] == 0
    # the 10-45 m target range pools the signs at 12 and 40 m
    assert report.target_range_count == 2 and report.target_range_recall == 1.0
    assert report.fp_per_100_empty == 0.0 and report.n_empty == 1


def test_misses_low_confidence_and_false_positives_are_counted(tiny_split):
    scripted = [
        [Detection("stop_sign", 0.3, (300.0, 200.0, 320.0, 220.0), "front")],  # found, but below threshold
        [Detection("stop_sign", 0.9, (0.0, 0.0, 10.0, 10.0), "front")],  # wrong place
        [],
        [Detection("stop_sign", 0.8, (5.0, 5.0, 50.0, 50.0), "front")],  # fires on an empty frame
    ]
    report = evaluate(_replay(scripted), tiny_split, conf_threshold=0.5, progress=False)
    assert report.recall_by_bin["35-45 m"] == 0.0 and report.mean_conf_by_bin["35-45 m"] == pytest.approx(0.3)
    assert report.recall_by_bin["5-15 m"] == 0.0
    assert report.target_range_recall == 0.0 and report.target_range_recall_ci95[0] == 0.0
    assert report.fp_per_100_empty == 100.0
    assert report.ap50["stop_sign"] < 0.5 and report.ap50["yield"] == 0.0


def test_pinhole_error_uses_the_detected_box_height(tiny_split):
    # A 20 px stop sign box: the pinhole estimate is 0.762 * 896 / 20 = 34.1 m against a true 40 m.
    scripted = [[Detection("stop_sign", 0.9, (300.0, 200.0, 320.0, 220.0), "front")], [], [], []]
    report = evaluate(_replay(scripted), tiny_split, conf_threshold=0.5, progress=False)
    f_px = 240 / np.tan(np.radians(15))
    assert report.pinhole_median_rel_err_by_bin["35-45 m"] == pytest.approx(abs(0.762 * f_px / 20 - 40) / 40, rel=1e-6)


def test_report_writes_markdown_and_plot(tiny_split, tmp_path):
    report = evaluate(_replay([[], [], [], []]), tiny_split, conf_threshold=0.5, progress=False)
    report_path, plot_path = write_report(report, tmp_path / "eval", "test", about="Trained for 6 epochs.")
    text = report_path.read_text()
    assert "| stop_sign |" in text and plot_path.stat().st_size > 1000
    assert text.splitlines()[:3] == ["# test", "", "Trained for 6 epochs."]


def _never_called(image, camera):
    raise AssertionError("an image was scored before the bad line was refused")


def _with_last_line(tiny_split, tmp_path, **changes):
    """A copy of the tiny split whose last line has `changes` (None deletes a key; "meta.KEY" reaches into meta)."""
    shutil.copytree(tiny_split, tmp_path / "d")
    path = tmp_path / "d" / "val.jsonl"
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    for key, value in changes.items():
        target, name = (lines[-1]["meta"], key[5:]) if key.startswith("meta.") else (lines[-1], key)
        if value is None:
            del target[name]
        else:
            target[name] = value
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return tmp_path / "d"


@pytest.mark.parametrize("changes, match", [
    # Each ended in an internal error, the meta ones only after the earlier images were scored.
    ({"image": 5}, "field 'image' is 5"),
    ({"classes": [["stop_sign"]]}, "field 'classes'"),
    ({"boxes": 5, "classes": 5}, "field 'boxes' is 5"),
    ({"meta.target_kind": None}, "field 'meta.target_kind' is missing"),
    ({"meta.dist_m": "far"}, "field 'meta.dist_m' is \"far\""),
    ({"image": "images/gone.png"}, "gone.png does not exist"),
])
def test_a_bad_line_or_missing_image_is_refused_before_any_image_is_scored(tiny_split, tmp_path, changes, match):
    data = _with_last_line(tiny_split, tmp_path, **changes)
    with pytest.raises(DatasetError, match=re.escape(match)) as info:
        evaluate(_never_called, data, conf_threshold=0.5, progress=False)
    assert f"val.jsonl:{len(FRAMES)}:" in str(info.value) and "\n" not in str(info.value)


def test_a_truncated_image_is_refused_before_any_is_scored_but_not_beyond_limit(tiny_split, tmp_path):
    data = _with_last_line(tiny_split, tmp_path)
    last = data / "images" / f"{len(FRAMES) - 1}.png"
    last.write_bytes(last.read_bytes()[:100])
    with pytest.raises(DatasetError, match="is cut short"):
        evaluate(_never_called, data, conf_threshold=0.5, progress=False)
    # --limit scores only the first images: one it never reads need not be whole.
    report = evaluate(_replay([[], []]), data, conf_threshold=0.5, limit=2, progress=False)
    assert report.n_images == 2
