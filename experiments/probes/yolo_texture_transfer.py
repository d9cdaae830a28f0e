"""Probe: how much of each shipped texture transfers to YOLOv3-tiny (--perception yolo)?

Drive-bys of the front camera (avsim.experiments.attacks.disappearance: the closed loop's frame spacing at
85 km/h, 60 m down to 4 m, lighting and sensor noise drawn per drive, the same drives for every
texture) under `--perception yolo` at its defaults, per texture:
- the disappearance rate at 10-41 m: frames with no stop-sign detection at or above the braking
  threshold matching the sign (IoU >= 0.3 with its true box), with its Wilson 95% interval;
- per drive, the farthest frame with a confident detection inside the braking gate (the pinhole
  estimate at most policy.trigger_dist_m), the frame `baseline` brakes on;
- the median predicted / true box height of the detected frames at 10-41 m.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/yolo_texture_transfer.py --drives 3 --town town07

It prints one table row per texture; a row takes about a minute a drive on a shared 2-core machine.
"""

from __future__ import annotations

import argparse

import numpy as np

from avsim.experiments.attacks.disappearance import drive_by_frames

SIGNS = ("clean", "chen", "eykholt", "lu_v2", "lu_v3", "yang", "driveby_detector", "driveby_coco", "driveby_ensemble")
RANGE_M = (10.0, 41.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--drives", type=int, default=3)
    parser.add_argument("--town", default="town07")
    parser.add_argument("--placement", default="standard")
    parser.add_argument("--detector", default="yolo", help="perception kind (yolo; detector or coco to compare)")
    parser.add_argument("--signs", default=",".join(SIGNS))
    args = parser.parse_args()
    print(f"{args.detector}, {args.town} {args.placement}, {args.drives} drive-bys per texture; disappearance at "
          f"{RANGE_M[0]:g}-{RANGE_M[1]:g} m")
    print("| texture | frames | missed | disappearance (95% interval) | first gated detection per drive [m] | "
          "height ratio |")
    print("|---|---|---|---|---|---|")
    for sign in args.signs.split(","):
        result = drive_by_frames(sign, args.detector, args.town, args.placement, args.drives)
        frames, missed, rate, (lo, hi) = result.disappearance(*RANGE_M)
        firsts = [result.first_confident_m(d, gated=True) for d in result.drives]
        first_text = ", ".join("none" if f is None else f"{f:.1f}" for f in firsts)
        ratio = result.height_ratio(*RANGE_M)
        print(f"| {sign} | {frames} | {missed} | {rate:.2f} ({lo:.2f}-{hi:.2f}) | {first_text} | "
              f"{'–' if np.isnan(ratio) else f'{ratio:.2f}'} |", flush=True)


if __name__ == "__main__":
    main()
