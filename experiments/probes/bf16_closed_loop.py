"""One-off probe: does the own detector's bf16 change closed-loop outcomes, run for run?

`perception.detector_precision = "bf16"` agrees with fp32 on held-out frames (recall inside fp32's
interval in every bin, AP equal to 4 decimals; docs/performance.md). Whether it can become the
default depends on the closed loop: a stop decision hangs on the first frame whose score crosses
the threshold, so a score moved by bf16 rounding near 0.5 can move the braking point by a frame or
more. This probe runs the same specs (experiment, cell, seed) twice, once with each precision,
and pairs them:

    MUJOCO_GL=egl python experiments/probes/bf16_closed_loop.py table3_stop_positions table2_attacked_defended

It prints every pair whose outcome differs or whose margin moved by more than 0.5 m, then how many
pairs are bit-identical and how many changed outcome (Wilson 95 %). It is not part of avsim; it
writes nothing. On 2 cores the two study tables (50 runs a precision) take about 15 minutes.
"""

from __future__ import annotations

import argparse
import dataclasses

from avsim.experiments.batch import run_batch
from avsim.experiments.reproduce import EXPERIMENTS_DIR, load_study, specs_for
from avsim.experiments.run_task import RunSpec
from avsim.stats import rate_with_interval

MARGIN_REPORTED_M = 0.5  # a margin moved by more than this is listed with the changed outcomes


def with_precision(spec: RunSpec, precision: str) -> RunSpec:
    perception = dataclasses.replace(spec.config.perception, detector_precision=precision)
    return dataclasses.replace(spec, config=dataclasses.replace(spec.config, perception=perception))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("experiments", nargs="+", help="experiment file stems under experiments/")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    specs = specs_for(load_study([EXPERIMENTS_DIR / f"{name}.toml" for name in args.experiments]))
    results = {}
    for precision in ("fp32", "bf16"):
        records = run_batch([with_precision(s, precision) for s in specs], workers=args.workers,
                            description=precision)
        results[precision] = {(r["experiment"], r["cell"], r["seed"]): r["result"] for r in records
                              if r["status"] == "ok"}
    pairs = sorted(set(results["fp32"]) & set(results["bf16"]))
    identical = changed = 0
    for key in pairs:
        a, b = results["fp32"][key], results["bf16"][key]
        identical += a["margin_m"] == b["margin_m"] and a["outcome"] == b["outcome"]
        changed += a["outcome"] != b["outcome"]
        if a["outcome"] != b["outcome"] or abs(a["margin_m"] - b["margin_m"]) > MARGIN_REPORTED_M:
            print(f"{' / '.join(map(str, key))}: fp32 {a['outcome']} ({a['margin_m']:+.2f} m), "
                  f"bf16 {b['outcome']} ({b['margin_m']:+.2f} m)")
    print(f"{len(pairs)} paired runs: {identical} with the same outcome and margin, bit for bit; "
          f"outcome changed in {changed} ({rate_with_interval(changed, len(pairs))})")


if __name__ == "__main__":
    main()
