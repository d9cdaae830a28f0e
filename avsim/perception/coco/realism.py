"""Do avsim's renders look like a stop sign to a detector trained on real photographs?

Runs the COCO CenterNet on a dataset written by `avsim detector make-data` (randomised
towns, lighting, fog, camera jitter) and reports, per `perception.coco_input` mode:
- stop-sign recall against distance (5-m bins, 5-60 m) per town and camera: a labelled stop
  sign counts as found when a `stop_sign` detection at or above the threshold overlaps it with
  IoU >= 0.5; 95% Wilson intervals;
- false `stop_sign` detections per frame, at the same threshold, on frames with no labelled
  stop sign, per town.
Each camera is searched in its deployed region of interest (`perception.front_roi_px`,
`side_roi_px`), as in the closed loop; no range limit (min_box_height_px) is applied, so the
figures are the network's own. Nothing is tuned to this detector.

    python -m avsim.perception.coco.realism --data data/coco_eval --modes resize,crop,upscale --out results/coco_realism

Several --data folders are scored and reported together.

Writes OUT/frames.jsonl (one line per frame and mode) and OUT/report.md, and prints the report.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from avsim.config import COCO_INPUTS, PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.ap import match_detections
from avsim.stats import wilson_interval

BIN_EDGES_M = tuple(range(5, 65, 5))  # 5-10, ..., 55-60 m
POOLED_RANGE_M = (10, 45)
_WORKER: dict = {}


def _init_worker(modes: tuple[str, ...], upscale: float, min_confidence: float) -> None:
    import torch

    from avsim.perception.coco.model import load_centernet
    from avsim.perception.coco.runner import CocoRunner

    torch.set_num_threads(1)
    model = load_centernet()
    _WORKER["runners"] = {mode: CocoRunner(model, mode, upscale, min_confidence) for mode in modes}
    defaults = PerceptionConfig()
    _WORKER["regions"] = {"front": defaults.front_roi_px, "side": defaults.side_roi_px}


def _score_frame(args: tuple[str, dict, float]) -> list[dict]:
    """One frame, every mode: the best matched stop-sign score and the false stop-sign scores."""
    import cv2

    data_dir, record, threshold = args
    image = np.ascontiguousarray(cv2.imread(str(Path(data_dir) / record["image"]))[..., ::-1])
    camera = record["meta"]["camera"]
    truth = np.asarray([b for b, c in zip(record["boxes"], record["classes"]) if c == "stop_sign"], float).reshape(-1, 4)
    rows = []
    for mode, runner in _WORKER["runners"].items():
        stops = [d for d in runner.detect(image, camera, region_px=_WORKER["regions"][camera]) if d.class_name == "stop_sign"]
        scores = np.asarray([d.confidence for d in stops])
        boxes = np.asarray([d.box_xyxy_px for d in stops]).reshape(-1, 4)
        # Match at the threshold: only detections that would count can find the sign.
        counted = scores >= threshold
        matched = np.zeros(len(stops), bool)
        matched[counted] = match_detections(boxes[counted], scores[counted], truth)
        best = max((d.confidence for d, hit in zip(stops, matched) if hit), default=0.0)
        rows.append({"image": record["image"], "mode": mode, "town": record["meta"]["town"], "camera": camera,
                     "dist_m": record["meta"]["dist_m"], "has_stop_sign": bool(len(truth)),
                     "has_any_sign": bool(record["classes"]),
                     "target_is_stop_sign": record["meta"]["target_kind"] == "stop_sign",
                     "found": bool(matched.any()), "best_matched_conf": round(float(best), 4),
                     "false_stop_signs": int(np.sum(counted & ~matched))})
    return rows


def score_dataset(data_dir: Path, modes: tuple[str, ...], threshold: float, workers: int, upscale: float,
                  min_confidence: float, limit: int | None = None) -> list[dict]:
    from tqdm import tqdm

    records = [json.loads(line) for line in (data_dir / "train.jsonl").read_text().splitlines()]
    records += [json.loads(line) for line in (data_dir / "val.jsonl").read_text().splitlines()] \
        if (data_dir / "val.jsonl").is_file() else []
    records = records[:limit] if limit else records
    jobs = [(str(data_dir), record, threshold) for record in records]
    rows: list[dict] = []
    with ProcessPoolExecutor(workers, initializer=_init_worker, initargs=(modes, upscale, min_confidence)) as pool:
        for frame_rows in tqdm(pool.map(_score_frame, jobs, chunksize=8), total=len(jobs), desc="COCO CenterNet", unit="img"):
            rows.extend(frame_rows)
    return rows


def _bin(dist_m: float) -> str | None:
    for lo, hi in zip(BIN_EDGES_M[:-1], BIN_EDGES_M[1:]):
        if lo <= dist_m < hi:
            return f"{lo}-{hi}"
    return None


def _cell(found: list[bool]) -> str:
    if not found:
        return "–"
    lo, hi = wilson_interval(sum(found), len(found))
    return f"{sum(found) / len(found):.2f} ({sum(found)}/{len(found)}; {lo:.2f}–{hi:.2f})"


def _recall_rows(rows: list[dict]) -> list[dict]:
    """Frames whose target is a labelled stop sign at a known distance (the recall population)."""
    return [r for r in rows if r["target_is_stop_sign"] and r["has_stop_sign"] and r["dist_m"] > 0]


def report(rows: list[dict], threshold: float) -> str:
    modes = sorted({r["mode"] for r in rows}, key=COCO_INPUTS.index)
    towns = sorted({r["town"] for r in rows})
    bins = [f"{lo}-{hi}" for lo, hi in zip(BIN_EDGES_M[:-1], BIN_EDGES_M[1:])]
    lines = [f"# COCO CenterNet on avsim renders ({len({r['image'] for r in rows})} frames)", "",
             f"Threshold {threshold}; a stop sign is found when a `stop_sign` detection at or above it overlaps the "
             "labelled box with IoU >= 0.5. Cells: recall (found/signs; 95% Wilson interval).", ""]
    recall_rows = _recall_rows(rows)
    for camera in ("front", "side"):
        lines += [f"## Recall by mode, {camera} camera, all towns", "",
                  "| mode | " + " | ".join(f"{b} m" for b in bins) + f" | {POOLED_RANGE_M[0]}-{POOLED_RANGE_M[1]} m pooled |",
                  "|---|" + "---|" * (len(bins) + 1)]
        for mode in modes:
            by_bin: dict[str, list[bool]] = defaultdict(list)
            pooled = []
            for r in recall_rows:
                if r["mode"] == mode and r["camera"] == camera:
                    by_bin[_bin(r["dist_m"]) or ""].append(r["found"])
                    if POOLED_RANGE_M[0] <= r["dist_m"] < POOLED_RANGE_M[1]:
                        pooled.append(r["found"])
            lines.append(f"| {mode} | " + " | ".join(_cell(by_bin[b]) for b in bins) + f" | {_cell(pooled)} |")
        lines.append("")
    for title, key in (("without a labelled stop sign", "has_stop_sign"), ("without any labelled sign", "has_any_sign")):
        lines += [f"## False `stop_sign` detections per frame, frames {title}", "",
                  "Cells: detections per frame (frames with at least one / frames).", "",
                  "| mode | " + " | ".join(towns) + " | all |", "|---|" + "---|" * (len(towns) + 1)]
        for mode in modes:
            cells = []
            for town in towns + ["all"]:
                frames = [r for r in rows if r["mode"] == mode and not r[key] and town in (r["town"], "all")]
                total = sum(r["false_stop_signs"] for r in frames)
                with_any = sum(r["false_stop_signs"] > 0 for r in frames)
                cells.append(f"{total / len(frames):.3f} ({with_any}/{len(frames)})" if frames else "–")
            lines.append(f"| {mode} | " + " | ".join(cells) + " |")
        lines.append("")
    for mode in modes:
        for camera in ("front", "side"):
            lines += [f"## Recall per town, {camera} camera, `{mode}`", "",
                      "| town | " + " | ".join(f"{b} m" for b in bins) + " |", "|---|" + "---|" * len(bins)]
            for town in towns:
                by_bin = defaultdict(list)
                for r in recall_rows:
                    if r["mode"] == mode and r["camera"] == camera and r["town"] == town:
                        by_bin[_bin(r["dist_m"]) or ""].append(r["found"])
                lines.append(f"| {town} | " + " | ".join(_cell(by_bin[b]) for b in bins) + " |")
            lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m avsim.perception.coco.realism", description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", nargs="+", required=True, help="datasets written by `avsim detector make-data`")
    parser.add_argument("--modes", default=",".join(COCO_INPUTS), help="comma-separated perception.coco_input values")
    parser.add_argument("--threshold", type=float, default=0.5, help="confidence that counts (the braking threshold)")
    parser.add_argument("--upscale", type=float, help="perception.coco_upscale for the upscale mode (default: the config's)")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--limit", type=int, help="only the first N frames")
    parser.add_argument("--out", default="results/coco_realism")
    args = parser.parse_args(argv)
    modes = tuple(m.strip() for m in args.modes.split(",") if m.strip())
    try:
        bad = [m for m in modes if m not in COCO_INPUTS]
        if bad or not modes:
            raise ConfigError(f"unknown --modes {bad}; choose from {', '.join(COCO_INPUTS)}")
        for data in map(Path, args.data):
            if not (data / "train.jsonl").is_file():
                raise ConfigError(f"{data} has no train.jsonl; make one with `avsim detector make-data --out {data}`")
        defaults = PerceptionConfig()
        upscale = defaults.coco_upscale if args.upscale is None else args.upscale
        if not 1 <= upscale <= 4:
            raise ConfigError(f"--upscale must be in [1, 4], got {upscale}")
        rows = []
        for data in map(Path, args.data):
            for row in score_dataset(data, modes, args.threshold, args.workers, upscale, defaults.min_confidence, args.limit):
                rows.append({**row, "image": str(data / row["image"])})
    except ConfigError as exc:
        print(f"avsim: error: {exc}", file=sys.stderr)
        return exc.exit_code
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "frames.jsonl", "w") as handle:
        for row in rows:
            handle.write(json.dumps(row) + "\n")
    text = report(rows, args.threshold)
    (out / "report.md").write_text(text)
    print(text)
    print(f"wrote {out}/frames.jsonl and {out}/report.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
