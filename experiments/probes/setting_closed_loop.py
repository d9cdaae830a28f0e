"""One-off probe: an experiment file's runs under the default renders and under a realism setting, paired.

`experiments/table3_realism.toml` runs Table III under four scenes as a shipped file. This probe asks
the same of any experiment file, once, without shipping another: it runs every (cell, seed) of the
files twice, under the default renders and under one of `avsim realism`'s settings (docs/realism.md),
with any further overrides applied to both, and prints per cell how many runs stopped before the sign
under each (Wilson 95 %), then every pair whose outcome differs:

    MUJOCO_GL=egl python experiments/probes/setting_closed_loop.py table2_attacked_defended --setting textured_sheeting_clusters_shadows
    MUJOCO_GL=egl python experiments/probes/setting_closed_loop.py table3_stop_positions --setting textured_sheeting_clusters_shadows --set perception.kind=coco
    MUJOCO_GL=egl python experiments/probes/setting_closed_loop.py coco_detector --cells "Town10" --setting scattered_clouds_low_clear --set scenario.sky=daylight

It is not part of avsim; it writes nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

from avsim.cli.overrides import parse_set
from avsim.config import with_overrides
from avsim.experiments.batch import run_batch
from avsim.experiments.reproduce import EXPERIMENTS_DIR, load_study, specs_for
from avsim.experiments.run_task import RunSpec
from avsim.realism.settings import BASELINE, SETTINGS
from avsim.stats import rate_with_interval


def stopped_before_sign(result: dict) -> bool:
    return result["sign_margin_m"] is not None and result["sign_margin_m"] >= 0


def spread(values: list) -> str:
    """"mean ± std" of the values that are not None, and how many are None."""
    known = [v for v in values if v is not None]
    text = f"{statistics.mean(known):.1f} ± {statistics.pstdev(known):.1f}" if known else "-"
    return text + (f" ({len(values) - len(known)} never)" if len(known) < len(values) else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("experiments", nargs="+", help="experiment file stems under experiments/")
    parser.add_argument("--setting", required=True, choices=tuple(SETTINGS))
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="applied to both runs of a pair")
    parser.add_argument("--cells", default="", metavar="TEXT", help="only the cells whose name contains TEXT")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    common = parse_set(args.set)
    paths = [EXPERIMENTS_DIR / f"{name}.toml" for name in args.experiments]
    specs = [s for s in specs_for(load_study(paths)) if args.cells in s.cell]
    if not specs:
        parser.error(f"no cell of {', '.join(args.experiments)} has {args.cells!r} in its name")
    results = {}
    for label, setting in (("default", BASELINE), (args.setting, args.setting)):
        start = time.monotonic()
        # the setting as `avsim reproduce --setting` applies it, --set on top of both
        runs = [dataclasses.replace(s, config=with_overrides(s.config, common))
                for s in specs_for(load_study(paths, setting=setting)) if args.cells in s.cell]
        records = run_batch(runs, workers=args.workers, description=label)
        results[label] = {(r["experiment"], r["cell"], r["seed"]): r["result"] for r in records if r["status"] == "ok"}
        print(f"{label}: {len(records)} runs in {(time.monotonic() - start) / 60:.1f} min")
    cells = list(dict.fromkeys((s.experiment, s.cell) for s in specs))
    print(f"\nStopped before the sign; where braking began and where the sign was first seen (bumper to sign, mean ± std [m]):")
    print(f"\n| cell | default | {args.setting} |\n|---|---|---|")
    for experiment, cell in cells:
        columns = []
        for label in ("default", args.setting):
            rows = [r for (e, c, _), r in results[label].items() if (e, c) == (experiment, cell)]
            columns.append(f"{rate_with_interval(sum(stopped_before_sign(r) for r in rows), len(rows))}; braking from "
                           f"{spread([r['dist_at_brake_m'] for r in rows])}, first seen {spread([r['first_detection_dist_m'] for r in rows])}")
        print(f"| {experiment} / {cell} | {columns[0]} | {columns[1]} |")
    pairs = sorted(set(results["default"]) & set(results[args.setting]))
    changed = 0
    for key in pairs:
        a, b = results["default"][key], results[args.setting][key]
        if stopped_before_sign(a) != stopped_before_sign(b):
            changed += 1
            print(f"{' / '.join(map(str, key))}: default {a['outcome']} ({a['sign_margin_m']:+.2f} m to the sign, braking "
                  f"from {a['dist_at_brake_m']} m), {args.setting} {b['outcome']} ({b['sign_margin_m']:+.2f} m, "
                  f"from {b['dist_at_brake_m']} m)")
    print(f"{len(pairs)} pairs; stopped before the sign under one and not the other: {changed} "
          f"({rate_with_interval(changed, len(pairs))})")


if __name__ == "__main__":
    main()
