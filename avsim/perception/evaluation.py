"""`avsim detector eval`: the detector's quality on the held-out split.

Reports, as markdown plus a PNG plot:
- AP at IoU 0.5 per class (all-point interpolation);
- stop-sign recall and mean confidence per distance bin (front camera, target stop signs);
- false positives per 100 sign-free frames, at the braking threshold;
- median relative error of the pinhole distance from detected boxes, per distance bin.

Distances are the camera's depth to the sign face [m], as recorded in the data's meta.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from avsim.config import CameraConfig
from avsim.control.pinhole import pinhole_distance_m
from avsim.perception.ap import average_precision, match_detections
from avsim.perception.base import SIGN_CLASSES, Detection

DIST_BINS_M = ((5, 15), (15, 25), (25, 35), (35, 45), (45, 60))
STOP_SIGN_HEIGHT_M = 0.762

Detect = Callable[[np.ndarray, str], list[Detection]]


@dataclass
class _ClassTally:
    scores: list[float] = field(default_factory=list)
    matched: list[bool] = field(default_factory=list)
    n_ground_truth: int = 0


@dataclass(frozen=True)
class EvalReport:
    ap50: dict[str, float]
    recall_by_bin: dict[str, float]
    mean_conf_by_bin: dict[str, float]
    count_by_bin: dict[str, int]
    fp_per_100_empty: float
    n_empty: int
    pinhole_median_rel_err_by_bin: dict[str, float]
    conf_threshold: float
    n_images: int


def _bin_name(lo: float, hi: float) -> str:
    return f"{lo}-{hi} m"


def evaluate(detect: Detect, data_dir: str | Path, conf_threshold: float, split: str = "val",
             limit: int | None = None, progress: bool = True) -> EvalReport:
    """Run `detect(image_rgb, camera)` (all detections, any score) over a split and score it."""
    from tqdm import tqdm

    data_dir = Path(data_dir)
    records = [json.loads(line) for line in (data_dir / f"{split}.jsonl").read_text().splitlines()]
    records = records[:limit] if limit else records
    tallies = {cls: _ClassTally() for cls in SIGN_CLASSES}
    f_px = CameraConfig().f_px
    per_bin_conf: dict[str, list[float]] = {_bin_name(*b): [] for b in DIST_BINS_M}
    per_bin_pinhole: dict[str, list[float]] = {_bin_name(*b): [] for b in DIST_BINS_M}
    false_positives, n_empty = 0, 0
    for record in tqdm(records, desc=f"evaluating {split}", disable=not progress):
        image = cv2.imread(str(data_dir / record["image"]))[..., ::-1]
        detections = detect(np.ascontiguousarray(image), record["meta"]["camera"])
        gt_boxes = np.asarray(record["boxes"], dtype=float).reshape(-1, 4)
        gt_classes = record["classes"]
        if not gt_classes:
            n_empty += 1
            false_positives += sum(d.confidence >= conf_threshold for d in detections)
        best_stop_conf, best_stop_det = 0.0, None
        for cls in SIGN_CLASSES:
            dets = [d for d in detections if d.class_name == cls]
            gt_of_class = gt_boxes[[c == cls for c in gt_classes]] if gt_classes else gt_boxes[:0]
            scores = np.asarray([d.confidence for d in dets])
            matched = match_detections(np.asarray([d.box_xyxy_px for d in dets]).reshape(-1, 4), scores, gt_of_class)
            tally = tallies[cls]
            tally.n_ground_truth += len(gt_of_class)
            tally.scores.extend(scores.tolist())
            tally.matched.extend(matched.tolist())
            if cls == "stop_sign":
                for det, hit in zip(dets, matched):
                    if hit and det.confidence > best_stop_conf:
                        best_stop_conf, best_stop_det = det.confidence, det
        meta = record["meta"]
        if meta["camera"] == "front" and meta["target_kind"] == "stop_sign" and "stop_sign" in gt_classes:
            for lo, hi in DIST_BINS_M:
                if lo <= meta["dist_m"] < hi:
                    per_bin_conf[_bin_name(lo, hi)].append(best_stop_conf)
                    if best_stop_det is not None and best_stop_conf >= conf_threshold and not best_stop_det.truncated:
                        estimate = pinhole_distance_m(STOP_SIGN_HEIGHT_M, f_px, best_stop_det.height_px)
                        per_bin_pinhole[_bin_name(lo, hi)].append(abs(estimate - meta["dist_m"]) / meta["dist_m"])
    return EvalReport(
        ap50={cls: average_precision(np.asarray(t.scores), np.asarray(t.matched, bool), t.n_ground_truth) for cls, t in tallies.items()},
        recall_by_bin={b: float(np.mean(np.asarray(v) >= conf_threshold)) if v else float("nan") for b, v in per_bin_conf.items()},
        mean_conf_by_bin={b: float(np.mean(v)) if v else float("nan") for b, v in per_bin_conf.items()},
        count_by_bin={b: len(v) for b, v in per_bin_conf.items()},
        fp_per_100_empty=100.0 * false_positives / n_empty if n_empty else float("nan"),
        n_empty=n_empty,
        pinhole_median_rel_err_by_bin={b: float(np.median(v)) if v else float("nan") for b, v in per_bin_pinhole.items()},
        conf_threshold=conf_threshold,
        n_images=len(records),
    )


def write_report(report: EvalReport, out_dir: str | Path, title: str) -> tuple[Path, Path]:
    """Write report.md and recall_vs_distance.png into out_dir."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    bins = list(report.recall_by_bin)
    centres = [(lo + hi) / 2 for lo, hi in DIST_BINS_M]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    ax.plot(centres, [report.recall_by_bin[b] for b in bins], "o-", label=f"recall (conf >= {report.conf_threshold})")
    ax.plot(centres, [report.mean_conf_by_bin[b] for b in bins], "s--", label="mean stop-sign confidence")
    ax.axhline(0.75, color="grey", lw=0.8, ls=":", label="study's clean-sign confidence (0.75)")
    ax.set_xlabel("distance to the stop sign [m]")
    ax.set_ylim(0, 1.05)
    ax.set_title("Stop-sign detection against distance (front camera, held-out split)")
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    plot_path = out / "recall_vs_distance.png"
    fig.savefig(plot_path)
    plt.close(fig)

    lines = [f"# {title}", "", f"{report.n_images} held-out images (town layout seed 0, sun elevation 40-55 deg); "
             f"confidence threshold {report.conf_threshold}.", "", "| class | AP@0.5 |", "|---|---|"]
    lines += [f"| {cls} | {ap:.3f} |" for cls, ap in report.ap50.items()]
    lines += ["", "| distance | stop signs | recall | mean confidence | median pinhole error |", "|---|---|---|---|---|"]
    for b in bins:
        lines.append(f"| {b} | {report.count_by_bin[b]} | {report.recall_by_bin[b]:.3f} | {report.mean_conf_by_bin[b]:.3f} | "
                     f"{100 * report.pinhole_median_rel_err_by_bin[b]:.1f}% |")
    lines += ["", f"False positives at the threshold: {report.fp_per_100_empty:.2f} per 100 sign-free frames "
              f"({report.n_empty} frames).", "", f"![recall and confidence against distance]({plot_path.name})", ""]
    report_path = out / "report.md"
    report_path.write_text("\n".join(lines))
    return report_path, plot_path
