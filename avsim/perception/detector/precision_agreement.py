"""Does bf16 change what the own detector finds? fp32 and bf16 scored on the same held-out frames.

    python -m avsim.perception.detector.precision_agreement --data data/signs [--limit N] [--conf 0.5]

Runs `avsim detector eval`'s scoring (`avsim.perception.evaluation.evaluate`) twice on one data set,
once per `perception.detector_precision`, and prints, per distance bin of the front camera's stop
signs: each precision's recall with its Wilson 95 % interval, and whether bf16's recall lies inside
fp32's interval; then AP per class and false positives per 100 sign-free frames. The frames are
whole 640x480 images (no region of interest), where both precisions see the same pixels.
"""

from __future__ import annotations

import sys
from pathlib import Path

from avsim.config import ARITHMETICS
from avsim.errors import AvsimError
from avsim.perception.evaluation import EvalReport, evaluate
from avsim.validation import OneLineArgumentParser, number_flag


def measure(data_dir: str | Path, conf_threshold: float, split: str = "val", limit: int | None = None,
            progress: bool = True) -> dict[str, EvalReport]:
    """One `EvalReport` per precision, on the same frames."""
    from avsim.perception.detector.infer import SignDetectorRunner
    from avsim.perception.detector.weights import resolve_weights_path

    reports = {}
    for precision in ARITHMETICS:
        runner = SignDetectorRunner(resolve_weights_path(""), conf_threshold=0.01, num_threads=1, precision=precision)
        reports[precision] = evaluate(runner.detect, data_dir, conf_threshold, split=split, limit=limit, progress=progress)
    return reports


def format_agreement(reports: dict[str, EvalReport]) -> str:
    """A markdown table: per bin, each precision's recall and interval, and whether bf16 is inside fp32's."""
    fp32, bf16 = reports["fp32"], reports["bf16"]
    lines = [f"stop-sign recall at confidence >= {fp32.conf_threshold} (front camera), fp32 against bf16:", "",
             "| bin | frames | fp32 recall (95 % CI) | bf16 recall (95 % CI) | bf16 inside fp32's CI | mean best score fp32 / bf16 |",
             "|---|---|---|---|---|---|"]
    inside = total = 0
    for name, count in fp32.count_by_bin.items():
        if count == 0:
            continue
        lo, hi = fp32.recall_ci95_by_bin[name]
        ok = lo - 1e-12 <= bf16.recall_by_bin[name] <= hi + 1e-12
        inside, total = inside + ok, total + 1
        blo, bhi = bf16.recall_ci95_by_bin[name]
        lines.append(f"| {name} | {count} | {fp32.recall_by_bin[name]:.3f} ({lo:.3f}-{hi:.3f}) | "
                     f"{bf16.recall_by_bin[name]:.3f} ({blo:.3f}-{bhi:.3f}) | {'yes' if ok else 'NO'} | "
                     f"{fp32.mean_conf_by_bin[name]:.5f} / {bf16.mean_conf_by_bin[name]:.5f} |")
    lines += ["", f"bf16 recall inside fp32's interval in {inside} of {total} bins", "",
              "| | fp32 | bf16 |", "|---|---|---|"]
    for cls in fp32.ap50:
        lines.append(f"| AP@0.5 {cls} | {fp32.ap50[cls]:.4f} | {bf16.ap50[cls]:.4f} |")
    lines.append(f"| false positives per 100 sign-free frames ({fp32.n_empty}) | {fp32.fp_per_100_empty:.2f} | "
                 f"{bf16.fp_per_100_empty:.2f} |")
    lines.append(f"| stop-sign recall, 10-45 m pooled ({fp32.target_range_count} frames) | {fp32.target_range_recall:.3f} | "
                 f"{bf16.target_range_recall:.3f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.perception.detector.precision_agreement`: score the detector in fp32 and in
    bf16 on the same held-out frames and print where they differ; returns the exit status.
    """
    parser = OneLineArgumentParser(prog="python -m avsim.perception.detector.precision_agreement",
                                   description=__doc__.split("\n")[0])
    parser.add_argument("--data", default="data/signs", help="dataset directory (`avsim detector make-data`)")
    parser.add_argument("--split", choices=("val", "train"), default="val")
    parser.add_argument("--conf", type=number_flag(0, 1, lo_open=True, hi_open=True), default=0.5,
                        help="confidence threshold for recall and false positives")
    parser.add_argument("--limit", type=number_flag(1, None, integer=True), help="score only the first N images")
    args = parser.parse_args(argv)
    try:  # a bad labels line or image is one line (the dataset is checked before the first image is scored)
        print(format_agreement(measure(args.data, args.conf, args.split, args.limit)))
    except AvsimError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    return 0

if __name__ == "__main__":
    sys.exit(main())
