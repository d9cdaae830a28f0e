"""`avsim detector eval`: the detector's quality on the held-out split.

Reports, as markdown plus a PNG plot:
- AP at IoU 0.5 per class (all-point interpolation);
- stop-sign recall, with its 95% Wilson score interval, and mean confidence per distance bin
  (front camera, target stop signs): a bin of 20 signs cannot tell 0.95 from 0.90;
- false positives per 100 sign-free frames, at the braking threshold;
- median relative error of the pinhole distance from detected boxes, per distance bin.

Distances are the camera's depth to the sign face [m], as recorded in the data's meta.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from avsim.config import CameraConfig
from avsim.perception.ap import average_precision, match_detections
from avsim.perception.base import SIGN_CLASSES, Detection
from avsim.perception.detector.data import (FINITE, MISSING, DatasetError, Record, check_image_files, decode_line,
                                            field_error, parse_object, read_rgb, split_lines)
from avsim.sensors.pinhole import pinhole_distance_m
from avsim.stats import wilson_interval

DIST_BINS_M = ((5, 15), (15, 25), (25, 35), (35, 45), (45, 60), (60, 80), (80, 100), (100, 120), (120, 140),
               (140, 160))
# The range over which the shipped model's recall target (>= 0.95) is stated, pooled.
TARGET_RANGE_M = (10, 45)
STOP_SIGN_HEIGHT_M = 0.762

Detect = Callable[[np.ndarray, str], list[Detection]]


@dataclass
class _ClassTally:
    scores: list[float] = field(default_factory=list)
    matched: list[bool] = field(default_factory=list)
    n_ground_truth: int = 0


@dataclass(frozen=True)
class EvalReport:
    """The detector's quality on a held-out split (module docstring). Dicts are keyed by class
    name (ap50) or distance bin ("5-15", camera depth to the sign face [m]); recalls are of target
    stop signs on the front camera with Wilson 95% intervals; false positives per 100 sign-free
    frames and confidences at `conf_threshold`."""

    ap50: dict[str, float]
    recall_by_bin: dict[str, float]
    recall_ci95_by_bin: dict[str, tuple[float, float]]
    target_range_recall: float  # pooled over TARGET_RANGE_M
    target_range_recall_ci95: tuple[float, float]
    target_range_count: int
    mean_conf_by_bin: dict[str, float]
    count_by_bin: dict[str, int]
    fp_per_100_empty: float
    n_empty: int
    pinhole_median_rel_err_by_bin: dict[str, float]
    conf_threshold: float
    n_images: int

    @property
    def half_recall_range_m(self) -> float | None:
        """The detector's range: the distance [m] at which its stop-sign recall falls below 0.5,
        interpolated linearly between the centres of the first bin under 0.5 and the bin before
        it; None if no measured bin falls below 0.5 (or the very first one does)."""
        centres = [((lo + hi) / 2, self.recall_by_bin[_bin_name(lo, hi)]) for lo, hi in DIST_BINS_M
                   if self.count_by_bin[_bin_name(lo, hi)] > 0]
        for (d0, r0), (d1, r1) in zip(centres, centres[1:]):
            if r0 >= 0.5 > r1:
                return d0 + (d1 - d0) * (r0 - 0.5) / (r0 - r1)
        return None


def _bin_name(lo: float, hi: float) -> str:
    return f"{lo}-{hi} m"


def eval_record(line: str, where: str, data_dir: Path) -> tuple[dict, Record]:
    """One labels line as the evaluation reads it, checked as training checks it (`parse_line`),
    plus the meta keys the scoring reads (camera, target_kind, dist_m); a one-line DatasetError
    naming FILE:LINE and the field, so no line fails after the images before it were scored.
    Returns (the line's JSON object, its `Record`)."""
    record = decode_line(line, where)
    parsed = parse_object(record, where, data_dir, SIGN_CLASSES)  # a dict whose meta is a dict, once it passes
    meta = record.get("meta", {})
    if not isinstance(meta.get("camera"), str):
        raise DatasetError(f"{where} has no meta.camera (the camera the image was rendered by); regenerate the dataset")
    if not isinstance(meta.get("target_kind"), str):
        raise field_error(where, "meta.target_kind", meta.get("target_kind", MISSING),
                          'the kind of the sign the view looks at, e.g. "stop_sign"')
    if not FINITE.contains(meta.get("dist_m", MISSING)):
        raise field_error(where, "meta.dist_m", meta.get("dist_m", MISSING),
                          "the camera's depth to that sign [m], a finite number (-1 when not in view)")
    return record, parsed


def evaluate(detect: Detect, data_dir: str | Path, conf_threshold: float, split: str = "val",
             limit: int | None = None, progress: bool = True) -> EvalReport:
    """Run `detect(image_rgb, camera)` (all detections, any score) over a split and score it.
    Every labels line, and every image to be scored, is checked before the first is scored."""
    from tqdm import tqdm

    data_dir = Path(data_dir)
    parsed = [eval_record(line, where, data_dir) for where, line in split_lines(data_dir, split)]
    if not parsed:  # a score over no image would be written as if it meant something
        raise DatasetError(f"{data_dir / split}.jsonl lists no images; evaluate another split (--split) or "
                           f"dataset (--data), or remake it with `avsim detector make-data --out {data_dir} --overwrite`")
    parsed = parsed[:limit]  # only the images --limit scores need to exist
    check_image_files([checked for _, checked in parsed])
    records = [record for record, _ in parsed]
    tallies = {cls: _ClassTally() for cls in SIGN_CLASSES}
    f_px = CameraConfig().f_px
    per_bin_conf: dict[str, list[float]] = {_bin_name(*b): [] for b in DIST_BINS_M}
    target_range_conf: list[float] = []
    per_bin_pinhole: dict[str, list[float]] = {_bin_name(*b): [] for b in DIST_BINS_M}
    false_positives, n_empty = 0, 0
    for record in tqdm(records, desc=f"evaluating {split}", disable=not progress):
        image = read_rgb(data_dir / record["image"])
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
            if TARGET_RANGE_M[0] <= meta["dist_m"] < TARGET_RANGE_M[1]:
                target_range_conf.append(best_stop_conf)
            for lo, hi in DIST_BINS_M:
                if lo <= meta["dist_m"] < hi:
                    per_bin_conf[_bin_name(lo, hi)].append(best_stop_conf)
                    if best_stop_det is not None and best_stop_conf >= conf_threshold and not best_stop_det.truncated:
                        estimate = pinhole_distance_m(STOP_SIGN_HEIGHT_M, f_px, best_stop_det.height_px)
                        per_bin_pinhole[_bin_name(lo, hi)].append(abs(estimate - meta["dist_m"]) / meta["dist_m"])
    target_hits = int(np.sum(np.asarray(target_range_conf) >= conf_threshold))
    return EvalReport(
        ap50={cls: average_precision(np.asarray(t.scores), np.asarray(t.matched, bool), t.n_ground_truth) for cls, t in tallies.items()},
        recall_by_bin={b: float(np.mean(np.asarray(v) >= conf_threshold)) if v else float("nan") for b, v in per_bin_conf.items()},
        recall_ci95_by_bin={b: wilson_interval(int(np.sum(np.asarray(v) >= conf_threshold)), len(v)) for b, v in per_bin_conf.items()},
        target_range_recall=target_hits / len(target_range_conf) if target_range_conf else float("nan"),
        target_range_recall_ci95=wilson_interval(target_hits, len(target_range_conf)),
        target_range_count=len(target_range_conf),
        mean_conf_by_bin={b: float(np.mean(v)) if v else float("nan") for b, v in per_bin_conf.items()},
        count_by_bin={b: len(v) for b, v in per_bin_conf.items()},
        fp_per_100_empty=100.0 * false_positives / n_empty if n_empty else float("nan"),
        n_empty=n_empty,
        pinhole_median_rel_err_by_bin={b: float(np.median(v)) if v else float("nan") for b, v in per_bin_pinhole.items()},
        conf_threshold=conf_threshold,
        n_images=len(records),
    )


def write_report(report: EvalReport, out_dir: str | Path, title: str, about: str = "") -> tuple[Path, Path]:
    """Write report.md and recall_vs_distance.png into out_dir; `about` (e.g. how the weights were trained) is a
    paragraph under the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    bins = list(report.recall_by_bin)
    centres = [(lo + hi) / 2 for lo, hi in DIST_BINS_M]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    recall = np.array([report.recall_by_bin[b] for b in bins])
    interval = np.array([report.recall_ci95_by_bin[b] for b in bins]).T  # (2, bins): low, high
    ax.errorbar(centres, recall, yerr=np.abs(interval - recall), fmt="o-", capsize=3,
                label=f"recall (conf >= {report.conf_threshold}), 95% interval")
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

    lines = [f"# {title}", "", *([about, ""] if about else []),
             f"{report.n_images} held-out images (town layout seed 0, sun elevation 40-55 deg); "
             f"confidence threshold {report.conf_threshold}.", "", "| class | AP@0.5 |", "|---|---|"]
    lines += [f"| {cls} | {ap:.3f} |" for cls, ap in report.ap50.items()]
    lines += ["", "| distance | stop signs | recall | recall, 95% interval | mean confidence | median pinhole error |",
              "|---|---|---|---|---|---|"]
    for b in bins:
        lo, hi = report.recall_ci95_by_bin[b]
        lines.append(f"| {b} | {report.count_by_bin[b]} | {report.recall_by_bin[b]:.3f} | {lo:.3f}–{hi:.3f} | "
                     f"{report.mean_conf_by_bin[b]:.3f} | {100 * report.pinhole_median_rel_err_by_bin[b]:.1f}% |")
    lo, hi = report.target_range_recall_ci95
    lines.append(f"| {TARGET_RANGE_M[0]}-{TARGET_RANGE_M[1]} m (target range, pooled) | {report.target_range_count} | "
                 f"{report.target_range_recall:.3f} | {lo:.3f}–{hi:.3f} | | |")
    half_range = report.half_recall_range_m
    if half_range is not None:
        lines += ["", f"Range: stop-sign recall falls below 0.5 at {half_range:.1f} m (interpolated between bin centres), "
                      f"where the stop sign is {STOP_SIGN_HEIGHT_M * CameraConfig().f_px / half_range:.1f} px tall in the "
                      f"front camera."]
    lines += ["", f"False positives at the threshold: {report.fp_per_100_empty:.2f} per 100 sign-free frames "
              f"({report.n_empty} frames).", "", f"![recall and confidence against distance]({plot_path.name})", ""]
    report_path = out / "report.md"
    report_path.write_text("\n".join(lines))
    return report_path, plot_path
