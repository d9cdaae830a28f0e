"""Do avsim's renders look like a stop sign to a detector trained on real photographs?

Runs a COCO network (`--network coco`, the CenterNet; `--network yolo`, YOLOv3-tiny) on a
dataset written by `avsim detector make-data` (randomised towns, lighting, fog, camera
jitter) and reports, per setting (a `perception.coco_input` / `yolo_input` mode at a
`perception.coco_precision` / `yolo_precision`):
- stop-sign recall against distance (5-m bins, 5-60 m) per town and camera: a labelled stop
  sign counts as found when a `stop_sign` detection at or above the threshold overlaps it with
  IoU >= 0.5; 95% Wilson intervals;
- the same recall counting any `stop_sign` detection at or above the threshold whose box is
  centred inside the labelled box ("centred"), for networks that box only part of the sign
  (YOLOv3-tiny often boxes just the legend, IoU < 0.5);
- false `stop_sign` detections per frame, at the same threshold, on frames with no labelled
  stop sign, per town.
Each camera is searched in its deployed region of interest (`perception.front_roi_px`,
`side_roi_px`), as in the closed loop; no range limit (min_box_height_px) is applied, so the
figures are the network's own. Nothing is tuned to this detector.

With several precisions (`--precisions fp32,bf16`), each other precision is also set beside
fp32 on the same frames: whether its recall per distance bin and its rate of frames with a
false stop sign lie inside fp32's Wilson 95% intervals, and how far its stop-sign scores and
boxes are from fp32's (`compare_precisions`).

    python -m avsim.perception.coco.realism --data data/coco_eval --modes resize,crop,upscale --out results/coco_realism
    python -m avsim.perception.coco.realism --data data/coco_eval --modes upscale --precisions fp32,bf16
    python -m avsim.perception.coco.realism --network yolo --data data/coco_eval --modes upscale --precisions fp32,bf16

Several --data folders are scored and reported together.

Writes OUT/frames.jsonl (one line per frame and mode) and OUT/report.md, and prints the report.
"""

from __future__ import annotations

import json
import os
import sys
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from avsim.config import ARITHMETICS, COCO_INPUTS, CameraConfig, PerceptionConfig
from avsim.errors import AvsimError, ConfigError
from avsim.outputs import check_output_folder, refuse_earlier_outputs
from avsim.perception.detector.data import MISSING, check_image_files, field_error, split_lines
from avsim.perception.evaluation import eval_record
from avsim.validation import OneLineArgumentParser, config_flag, number_flag
from avsim.perception.ap import box_iou, match_detections
from avsim.perception.cpu_bf16 import arithmetic, arithmetics_here
from avsim.sensors.regions import regions_px
from avsim.stats import wilson_interval

BIN_EDGES_M = tuple(range(5, 65, 5))  # 5-10, ..., 55-60 m
POOLED_RANGE_M = (10, 45)
NETWORKS = {"coco": "COCO CenterNet", "yolo": "YOLOv3-tiny"}
_WORKER: dict = {}


def _init_worker(network: str, settings: tuple[tuple[str, str], ...], upscale: float, min_confidence: float) -> None:
    import torch

    from avsim.perception.factory import build_frame_detector

    torch.set_num_threads(1)
    _WORKER["runners"] = {(mode, precision): build_frame_detector(PerceptionConfig(
        kind=network, min_confidence=min_confidence, **{f"{network}_input": mode, f"{network}_precision": precision,
                                                        f"{network}_upscale": upscale}))
        for mode, precision in settings}
    defaults = PerceptionConfig()
    _WORKER["regions"] = regions_px(defaults, CameraConfig())  # make-data renders at the default camera


def _score_frame(args: tuple[str, dict, float]) -> list[dict]:
    """One frame, every setting: the best matched stop-sign score, the false stop-sign count,
    and every stop-sign detection (score and box, for comparing precisions)."""
    import cv2

    data_dir, record, threshold = args
    image = np.ascontiguousarray(cv2.imread(str(Path(data_dir) / record["image"]))[..., ::-1])
    camera = record["meta"]["camera"]
    truth = np.asarray([b for b, c in zip(record["boxes"], record["classes"]) if c == "stop_sign"], float).reshape(-1, 4)
    rows = []
    for (mode, precision), runner in _WORKER["runners"].items():
        stops = [d for d in runner.detect(image, camera, region_px=_WORKER["regions"][camera]) if d.class_name == "stop_sign"]
        scores = np.asarray([d.confidence for d in stops])
        boxes = np.asarray([d.box_xyxy_px for d in stops]).reshape(-1, 4)
        # Match at the threshold: only detections that would count can find the sign.
        counted = scores >= threshold
        matched = np.zeros(len(stops), bool)
        matched[counted] = match_detections(boxes[counted], scores[counted], truth)
        best = max((d.confidence for d, hit in zip(stops, matched) if hit), default=0.0)
        centres = (boxes[:, :2] + boxes[:, 2:]) / 2
        centred = counted & ((centres[:, None, :] >= truth[None, :, :2]) & (centres[:, None, :] <= truth[None, :, 2:])
                             ).all(axis=-1).any(axis=1)
        rows.append({"image": record["image"], "mode": mode, "precision": precision, "setting": f"{mode} {precision}",
                     "town": record["meta"]["town"], "camera": camera,
                     "dist_m": record["meta"]["dist_m"], "has_stop_sign": bool(len(truth)),
                     "has_any_sign": bool(record["classes"]),
                     "target_is_stop_sign": record["meta"]["target_kind"] == "stop_sign",
                     "found": bool(matched.any()), "found_centred": bool(centred.any()),
                     "best_matched_conf": round(float(best), 4),
                     "false_stop_signs": int(np.sum(counted & ~matched)),
                     "stop_signs": [[float(d.confidence), *map(float, d.box_xyxy_px)] for d in stops]})
    return rows


def read_frames(data_dir: Path, limit: int | None = None) -> list[dict]:
    """The labels lines of the dataset (train, then val; the first `limit`), each checked as `avsim detector eval`
    checks it, with the meta.town this report groups by, and each image's file: a one-line DatasetError naming
    FILE:LINE before the first frame is scored, not a worker's traceback after the others were."""
    splits = ("train", "val") if (data_dir / "val.jsonl").is_file() else ("train",)
    lines = [(where, line) for split in splits for where, line in split_lines(data_dir, split)][:limit]
    checked = [(*eval_record(line, where, data_dir), where) for where, line in lines]
    for record, _, where in checked:
        town = record["meta"].get("town", MISSING)
        if not isinstance(town, str):
            raise field_error(where, "meta.town", town, 'the town it was rendered in, e.g. "town07"')
    check_image_files([parsed for _, parsed, _ in checked])
    return [record for record, _, _ in checked]


def score_dataset(data_dir: Path, settings: tuple[tuple[str, str], ...], threshold: float, workers: int, upscale: float,
                  min_confidence: float, limit: int | None = None, network: str = "coco") -> list[dict]:
    """Rows of `_score_frame` for every frame of the dataset (train, then val) and setting (mode, precision)."""
    from tqdm import tqdm

    records = read_frames(data_dir, limit)
    jobs = [(str(data_dir), record, threshold) for record in records]
    rows: list[dict] = []
    with ProcessPoolExecutor(workers, initializer=_init_worker, initargs=(network, settings, upscale, min_confidence)) as pool:
        for frame_rows in tqdm(pool.map(_score_frame, jobs, chunksize=8), total=len(jobs), desc=NETWORKS[network], unit="img"):
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


def _settings(rows: list[dict]) -> list[str]:
    order = {(m, p): i for i, (m, p) in enumerate((m, p) for m in COCO_INPUTS for p in ARITHMETICS)}
    return [f"{m} {p}" for m, p in sorted({(r["mode"], r["precision"]) for r in rows}, key=order.get)]


def report(rows: list[dict], threshold: float, network: str = "coco") -> str:
    """The Markdown report of scored frames `rows` (one dict per frame and setting, as written to
    frames.jsonl) at detection `threshold`: recall per 5-m distance bin [m] and camera with Wilson
    95% intervals, false stop signs per frame per town, the precisions compared, recall per town."""
    settings = _settings(rows)
    towns = sorted({r["town"] for r in rows})
    bins = [f"{lo}-{hi}" for lo, hi in zip(BIN_EDGES_M[:-1], BIN_EDGES_M[1:])]
    lines = [f"# {NETWORKS[network]} on avsim renders ({len({r['image'] for r in rows})} frames)", "",
             f"Threshold {threshold}; a stop sign is found when a `stop_sign` detection at or above it overlaps the "
             "labelled box with IoU >= 0.5. Cells: recall (found/signs; 95% Wilson interval). A setting is "
             f"`perception.{network}_input` and `perception.{network}_precision`.", ""]
    recall_rows = _recall_rows(rows)
    for camera in ("front", "side"):
        lines += [f"## Recall by setting, {camera} camera, all towns", "",
                  "| setting | " + " | ".join(f"{b} m" for b in bins) + f" | {POOLED_RANGE_M[0]}-{POOLED_RANGE_M[1]} m pooled |",
                  "|---|" + "---|" * (len(bins) + 1)]
        for setting in settings:
            by_bin: dict[str, list[bool]] = defaultdict(list)
            pooled = []
            for r in recall_rows:
                if r["setting"] == setting and r["camera"] == camera:
                    by_bin[_bin(r["dist_m"]) or ""].append(r["found"])
                    if POOLED_RANGE_M[0] <= r["dist_m"] < POOLED_RANGE_M[1]:
                        pooled.append(r["found"])
            lines.append(f"| {setting} | " + " | ".join(_cell(by_bin[b]) for b in bins) + f" | {_cell(pooled)} |")
        lines.append("")
    for title, key in (("without a labelled stop sign", "has_stop_sign"), ("without any labelled sign", "has_any_sign")):
        lines += [f"## False `stop_sign` detections per frame, frames {title}", "",
                  "Cells: detections per frame (frames with at least one / frames).", "",
                  "| setting | " + " | ".join(towns) + " | all |", "|---|" + "---|" * (len(towns) + 1)]
        for setting in settings:
            cells = []
            for town in towns + ["all"]:
                frames = [r for r in rows if r["setting"] == setting and not r[key] and town in (r["town"], "all")]
                total = sum(r["false_stop_signs"] for r in frames)
                with_any = sum(r["false_stop_signs"] > 0 for r in frames)
                cells.append(f"{total / len(frames):.3f} ({with_any}/{len(frames)})" if frames else "–")
            lines.append(f"| {setting} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += compare_precisions(rows)
    criteria = [("found", "IoU >= 0.5")] + ([("found_centred", "centred")] if "found_centred" in rows[0] else [])
    for setting in settings:
        for key, criterion in criteria:
            for camera in ("front", "side"):
                lines += [f"## Recall per town, {camera} camera, `{setting}`, {criterion}", "",
                          "| town | " + " | ".join(f"{b} m" for b in bins) + f" | {POOLED_RANGE_M[0]}-{POOLED_RANGE_M[1]} m pooled |",
                          "|---|" + "---|" * (len(bins) + 1)]
                for town in towns:
                    by_bin, pooled = defaultdict(list), []
                    for r in recall_rows:
                        if r["setting"] == setting and r["camera"] == camera and r["town"] == town:
                            by_bin[_bin(r["dist_m"]) or ""].append(r[key])
                            if POOLED_RANGE_M[0] <= r["dist_m"] < POOLED_RANGE_M[1]:
                                pooled.append(r[key])
                    lines.append(f"| {town} | " + " | ".join(_cell(by_bin[b]) for b in bins) + f" | {_cell(pooled)} |")
                lines.append("")
    return "\n".join(lines)


def _inside(hits: int, n: int, reference: list[bool]) -> str:
    """"k/n (yes|NO)": whether hits/n lies inside the reference proportion's Wilson 95% interval."""
    lo, hi = wilson_interval(sum(reference), len(reference))
    return f"{hits}/{n} ({'yes' if lo <= hits / n <= hi else 'NO'})" if n else "–"


def _twin_deviations(reference: list[list[float]], other: list[list[float]]) -> tuple[list[float], list[float], int]:
    """For each reference stop sign [score, x0, y0, x1, y1], the other's detection overlapping it most
    (IoU >= 0.5): (|score difference|s, largest |edge difference| [px]s, reference rows without a twin)."""
    if not reference:
        return [], [], 0
    ref, oth = np.asarray(reference).reshape(-1, 5), np.asarray(other).reshape(-1, 5)
    if not len(oth):
        return [], [], len(ref)
    ious = box_iou(ref[:, 1:], oth[:, 1:])
    twin = ious.argmax(axis=1)
    has = ious[np.arange(len(ref)), twin] >= 0.5
    scores = np.abs(ref[has, 0] - oth[twin[has], 0])
    edges = np.abs(ref[has, 1:] - oth[twin[has], 1:]).max(axis=1)
    return scores.tolist(), edges.tolist(), int((~has).sum())


def compare_precisions(rows: list[dict]) -> list[str]:
    """Each precision other than fp32 beside fp32 of the same mode, on the same frames: recall per
    camera and distance bin and the share of stop-sign-free frames with a false stop sign, each
    checked against fp32's Wilson 95% interval; and the stop-sign score and box deviations."""
    lines = []
    recall_rows = _recall_rows(rows)
    bins = [f"{lo}-{hi}" for lo, hi in zip(BIN_EDGES_M[:-1], BIN_EDGES_M[1:])] + ["pooled"]
    for mode, precision in sorted({(r["mode"], r["precision"]) for r in rows if r["precision"] != "fp32"}):
        base, other = f"{mode} fp32", f"{mode} {precision}"
        if not any(r["setting"] == base for r in rows):
            continue
        lines += [f"## `{other}` beside `{base}`, same frames", "",
                  f"Cells: `{base}` found/signs (95% Wilson interval); `{other}` found/signs (inside that interval?).", "",
                  "| camera | " + " | ".join(f"{b} m" if b != "pooled" else f"{POOLED_RANGE_M[0]}-{POOLED_RANGE_M[1]} m" for b in bins)
                  + " |", "|---|" + "---|" * len(bins)]
        checks = outside = 0
        for camera in ("front", "side"):
            cells = []
            for b in bins:
                def found(setting: str) -> list[bool]:
                    return [r["found"] for r in recall_rows if r["setting"] == setting and r["camera"] == camera
                            and (POOLED_RANGE_M[0] <= r["dist_m"] < POOLED_RANGE_M[1] if b == "pooled" else _bin(r["dist_m"]) == b)]
                reference, theirs = found(base), found(other)
                if not reference:
                    cells.append("–")
                    continue
                cell = _inside(sum(theirs), len(theirs), reference)
                checks, outside = checks + 1, outside + cell.endswith("(NO)")
                cells.append(f"{_cell(reference)}; {cell}")
            lines.append(f"| {camera} | " + " | ".join(cells) + " |")
        lines += ["", "Frames without a labelled stop sign that have a false `stop_sign` detection:", "",
                  "| town | " + f"`{base}` | `{other}` |", "|---|---|---|"]
        for town in sorted({r["town"] for r in rows}) + ["all"]:
            def false_frames(setting: str) -> list[bool]:
                return [r["false_stop_signs"] > 0 for r in rows
                        if r["setting"] == setting and not r["has_stop_sign"] and town in (r["town"], "all")]
            reference, theirs = false_frames(base), false_frames(other)
            cell = _inside(sum(theirs), len(theirs), reference)
            checks, outside = checks + 1, outside + cell.endswith("(NO)")
            lines.append(f"| {town} | {_cell(reference)} | {cell} |")
        score_dev, edge_dev, missing = [], [], 0
        flips = 0
        by_frame = {(r["image"], r["setting"]): r for r in rows}
        for r in rows:
            if r["setting"] != base:
                continue
            twin = by_frame[r["image"], other]
            scores, edges, lost = _twin_deviations(r["stop_signs"], twin["stop_signs"])
            score_dev += scores
            edge_dev += edges
            missing += lost
            flips += r["found"] != twin["found"]
        lines += ["", f"{checks - outside} of {checks} checks inside fp32's interval.", ""]
        if score_dev:
            sd, ed = np.asarray(score_dev), np.asarray(edge_dev)
            lines += [f"Stop-sign detections of `{base}` (score >= min_confidence) and their `{other}` twins (the "
                      f"detection overlapping most, IoU >= 0.5): {len(sd)} pairs, {missing} without a twin. "
                      f"|score difference|: median {np.median(sd):.4f}, 95th percentile {np.percentile(sd, 95):.4f}, "
                      f"max {sd.max():.4f}. Largest |box edge difference| [image px]: median {np.median(ed):.3f}, "
                      f"95th percentile {np.percentile(ed, 95):.3f}, max {ed.max():.3f}. Frames whose labelled stop sign "
                      f"is found by one and not the other: {flips}.", ""]
    return lines


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.perception.coco.realism` (module docstring); returns the exit status."""
    parser = OneLineArgumentParser(prog="python -m avsim.perception.coco.realism", description=__doc__.split("\n\n")[0])
    parser.add_argument("--network", choices=tuple(NETWORKS), default="coco", help="coco (default) or yolo")
    parser.add_argument("--data", nargs="+", required=True, help="datasets written by `avsim detector make-data`")
    parser.add_argument("--modes", default=",".join(COCO_INPUTS), help="comma-separated perception.<network>_input values")
    parser.add_argument("--precisions", help="comma-separated perception.<network>_precision values (default: the "
                                             "config's); fp32 among several is the reference")
    parser.add_argument("--threshold", type=number_flag(0, 1, lo_open=True, hi_open=True), default=0.5, help="confidence that counts (the braking threshold)")
    parser.add_argument("--upscale", type=config_flag(PerceptionConfig, "coco_upscale"),
                        help="perception.<network>_upscale for the upscale mode (default: the config's)")
    parser.add_argument("--workers", type=number_flag(1, 64, integer=True), default=min(2, os.cpu_count() or 1))
    parser.add_argument("--limit", type=number_flag(1, None, integer=True), help="only the first N frames")
    parser.add_argument("--out", help="output folder (default results/<network>_realism)")
    args = parser.parse_args(argv)
    defaults = PerceptionConfig()
    if args.precisions is None:  # what the config's precision runs as on this CPU
        args.precisions = arithmetic(getattr(defaults, f"{args.network}_precision"), f"perception.{args.network}_precision")
    if args.out is None:
        args.out = f"results/{args.network}_realism"
    modes = tuple(m.strip() for m in args.modes.split(",") if m.strip())
    precisions = tuple(p.strip() for p in args.precisions.split(",") if p.strip())
    try:
        bad = [m for m in modes if m not in COCO_INPUTS]
        if bad or not modes:
            raise ConfigError(f"unknown --modes {bad}; choose from {', '.join(COCO_INPUTS)}")
        bad = [p for p in precisions if p not in ARITHMETICS]
        if bad or not precisions:
            raise ConfigError(f"unknown --precisions {bad}; choose from {', '.join(ARITHMETICS)}")
        if "bf16" in precisions and "bf16" not in arithmetics_here():
            raise ConfigError("--precisions bf16 needs a CPU on which oneDNN runs bfloat16 (AVX-512), and this one "
                              "has none; use --precisions fp32")
        for data in map(Path, args.data):
            if not (data / "train.jsonl").is_file():
                raise ConfigError(f"{data} has no train.jsonl; make one with `avsim detector make-data --out {data}`")
        out = check_output_folder(args.out, "--out")
        refuse_earlier_outputs(out, ("frames.jsonl", "report.md"))  # written only after every frame is scored
        upscale = getattr(defaults, f"{args.network}_upscale") if args.upscale is None else args.upscale
        if not 1 <= upscale <= 4:
            raise ConfigError(f"--upscale must be in [1, 4], got {upscale}")
        rows = []
        for data in map(Path, args.data):
            for row in score_dataset(data, tuple((m, p) for m in modes for p in precisions), args.threshold, args.workers,
                                     upscale, defaults.min_confidence, args.limit, args.network):
                rows.append({**row, "image": str(data / row["image"])})
    except AvsimError as exc:  # a bad flag, dataset or output folder: one line, before or instead of the scoring
        print(f"avsim: error: {exc}", file=sys.stderr)
        return exc.exit_code
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "frames.jsonl", "w") as handle:
        for row in rows:
            handle.write(json.dumps(row) + "\n")
    text = report(rows, args.threshold, args.network)
    (out / "report.md").write_text(text)
    print(text)
    print(f"wrote {out}/frames.jsonl and {out}/report.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
