"""One-off probe: how the runs of one or more `avsim reproduce` folders stopped, or why they did not.

Made for the table of trainings in docs/realism_networks.md ("The recipe's spread over training seeds"), where
each set of weights ran Table II's far cells over 30 seeds and what mattered was where each run began braking:

    avsim reproduce --seeds 30 --experiments experiments/table2_attacked_defended.toml \
        --cells 'Town03 far' 'Town10 far' --set perception.weights_path=W --rrd none --out results/far_W
    python experiments/probes/braking_onsets.py results/far_W results/far_other

For each folder (its newest batch) and each experiment in it, it prints the finished runs that needed a stop and
sorts them by the outcome each record holds: stopped for the sign (before it, and not resting beyond the braking
gate), stopped for something else first (came to rest beyond the gate: a phantom braked the car), never braked,
braked too late (ran past after braking), and timed out before the sign. Beside each kind, the distances before the sign at which braking began [m]: their
range, and the median over every run that braked. The Wilson 95 % interval is the stopped-for-the-sign rate's.
It reads `runs.jsonl` only and writes nothing; it is not part of avsim.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from avsim.experiments.results_file import read_records
from avsim.metrics import STOPPED_BEFORE_SIGN, record_rested_beyond_gate
from avsim.stats import rate_with_interval


def newest_runs_file(folder: Path) -> Path:
    """`runs.jsonl` of the newest batch under an `avsim reproduce --out` folder (or the file itself)."""
    if folder.is_file():
        return folder
    batches = sorted(folder.glob("*/runs.jsonl"))
    if not batches:
        raise SystemExit(f"braking_onsets.py: no */runs.jsonl under {folder}: pass an `avsim reproduce --out` folder")
    return batches[-1]


# The record's outcome -> the table's column; the stops split further by where the car came to rest (kind_of).
KIND_OF_OUTCOME = {"never_braked": "never braked", "ran_past_sign": "too late", "timed_out_before_sign": "timed out"}


def kind_of(result: dict) -> str:
    """One run's result record -> "for the sign", "something else first", or its outcome's KIND_OF_OUTCOME."""
    if result["outcome"] in STOPPED_BEFORE_SIGN:
        return "something else first" if record_rested_beyond_gate(result) else "for the sign"
    return KIND_OF_OUTCOME[result["outcome"]]


def span(values: list[float]) -> str:
    """"lo–hi" [m], one decimal; "" for none."""
    return f"{min(values):.1f}–{max(values):.1f}" if values else ""


def describe(results: list[dict]) -> str:
    """One line: each kind's count (the first with its Wilson interval) and where its runs began braking, then
    the median onset over every run that braked."""
    kinds = {kind: [r for r in results if kind_of(r) == kind]
             for kind in ("for the sign", "something else first", *KIND_OF_OUTCOME.values())}
    parts = []
    for kind, runs in kinds.items():
        count = rate_with_interval(len(runs), len(results)) if kind == "for the sign" else str(len(runs))
        onsets = [r["dist_at_brake_m"] for r in runs if r.get("dist_at_brake_m") is not None]
        where = f", braking began {span(onsets)} m out" if onsets else ""
        parts.append(f"{kind} {count}{where}")
    onsets = [r["dist_at_brake_m"] for r in results if r.get("dist_at_brake_m") is not None]
    median = f"; median onset {statistics.median(onsets):.1f} m" if onsets else ""
    return "; ".join(parts) + median


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+", help="`avsim reproduce --out` folders (or runs.jsonl files)")
    args = parser.parse_args()
    for folder in args.folders:
        lines = read_records(newest_runs_file(folder))
        finished = [line for line in lines if line["status"] == "ok" and line["result"].get("stop_required", True)]
        print(f"{folder}: {len(finished)} finished runs that needed a stop, {len(lines) - len(finished)} others")
        for experiment in sorted({line["experiment"] for line in finished}):
            results = [line["result"] for line in finished if line["experiment"] == experiment]
            print(f"  {experiment}: {describe(results)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
