"""One-off probe: are the COCO networks' false stop signs on Town07's tree crowns caused by the crowns' facets?

avsim draws MuJoCo's curved geoms coarsely for speed (`avsim.world.scene.CURVE_SLICES`, `CURVE_STACKS`: 12
slices and 6 stacks, against MuJoCo's 28 and 16), so a solid crown's outline is a polygon of about 12 sides,
next to an octagonal sign. A polygon of N sides strays from its circle by r (1 - cos(pi / N)): 3.4 % of the
radius at N = 12, so about 5 px for a 10 m tree's crown (vertical semi-axis 3.3 m) 20 m from the study
camera (f = 896 px). The variants:

- `facets_12x6`: as deployed;
- `facets_28x16`: MuJoCo's own default;
- `facets_48x24`: under half a pixel for that crown at 20 m (0.2 % of the radius; the stacks' outline has
  2 x 24 sides).

For each it runs the realism benchmark's default renders in Town07 and Town03 in this process (the constants
patched; `run_benchmark` with one worker) with the COCO CenterNet and NanoDet, and writes OUT/report.md,
OUT/recall.png and OUT/frames.jsonl as `avsim realism` does, one "setting" per variant. It prints the
false stop signs per network and variant, and the frames that have one under a variant and not as
deployed, and the other way.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/crown_tessellation.py 18 results/crown_tessellation

Measured here: docs/realism_foliage.md, "Not the crowns' facets".
"""

import json
import sys
from dataclasses import replace
from pathlib import Path

from avsim.realism import report as report_module
from avsim.realism.benchmark import BenchmarkPlan, run_benchmark
from avsim.realism.report import report, write_figure
from avsim.realism.settings import BASELINE, SETTINGS
from avsim.world import scene

# name: (slices, stacks)
VARIANTS = {"facets_12x6": (12, 6), "facets_28x16": (28, 16), "facets_48x24": (48, 24)}
NETWORKS = ("coco", "nanodet")


def _frames_with_false_stop_signs(rows: list[dict], variant: str, network: str) -> set[tuple]:
    return {(r["town"], r["scene"], r["frame"]) for r in rows
            if r["setting"] == variant and r["network"] == network and r["false_stop_signs"]}


def main(draws: int, out: Path) -> None:
    if (scene.CURVE_SLICES, scene.CURVE_STACKS) != VARIANTS["facets_12x6"]:
        raise SystemExit("the deployed tessellation changed: update VARIANTS")
    settings = {name: replace(SETTINGS[BASELINE], name=name, why=f"{slices} slices, {stacks} stacks")
                for name, (slices, stacks) in VARIANTS.items()}
    # The report describes each setting by its registered name; the variants exist only in this probe.
    report_module.SETTINGS = {**SETTINGS, **settings}
    rows = []
    for name, (slices, stacks) in VARIANTS.items():
        scene.CURVE_SLICES, scene.CURVE_STACKS = slices, stacks
        rows += run_benchmark(BenchmarkPlan((settings[name],), ("town07", "town03"), draws, NETWORKS), workers=1)
    out.mkdir(parents=True, exist_ok=True)
    (out / "frames.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    (out / "report.md").write_text(report(rows, 0.5) + "\n")
    write_figure(rows, out / "recall.png")
    for network in NETWORKS:
        deployed = _frames_with_false_stop_signs(rows, "facets_12x6", network)
        for name in VARIANTS:
            frames = _frames_with_false_stop_signs(rows, name, network)
            print(f"{network} {name}: {len(frames)} frames with a false stop sign; "
                  f"{len(frames - deployed)} not as deployed, {len(deployed - frames)} only as deployed")


if __name__ == "__main__":
    main(int(sys.argv[1]), Path(sys.argv[2]))
