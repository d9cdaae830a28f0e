"""One-off probe: how the see-through crowns' results move with their two chosen constants
(`avsim.world.foliage`): the porosity at the ends of Wilkinson's broadleaf range (0.11, lime; 0.24, birch
and alder) instead of its median 0.19, and the assumed cluster radius halved and doubled (0.15-0.35 m,
0.6-1.4 m, each still at most 0.4 of the crown's smallest semi-axis).

For each variant it runs the realism benchmark's `clusters` setting in Town07 in this process (the
constants patched; `run_benchmark` with one worker), and one closed-loop run (Town07 standard, YOLOv3-tiny
bf16, baseline policy, seed 0). It writes OUT/report.md, OUT/recall.png and OUT/frames.jsonl as
`avsim realism` does, one "setting" per variant, and prints the closed-loop outcomes.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/foliage_sensitivity.py 12 results/foliage_sensitivity

Measured here: docs/realism_foliage.md, "See-through tree crowns".
"""

import json
import sys
from dataclasses import replace
from pathlib import Path

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.realism.benchmark import BenchmarkPlan, run_benchmark
from avsim.realism import report as report_module
from avsim.realism.report import report, write_figure
from avsim.realism.settings import SETTINGS
from avsim.world import foliage
from avsim.world.scene import compose_scene

# name: (porosity, cluster radius range [m])
VARIANTS = {
    "clusters": (foliage.CROWN_POROSITY, foliage.CLUSTER_RADIUS_M),
    "clusters_porosity_0.11": (0.11, foliage.CLUSTER_RADIUS_M),
    "clusters_porosity_0.24": (0.24, foliage.CLUSTER_RADIUS_M),
    "clusters_radius_x0.5": (foliage.CROWN_POROSITY, (0.15, 0.35)),
    "clusters_radius_x2": (foliage.CROWN_POROSITY, (0.6, 1.4)),
}


def main(draws: int, out: Path) -> None:
    rows = []
    outcomes = []
    settings = {name: replace(SETTINGS["clusters"], name=name, why=f"porosity {porosity}, cluster radius {radius_m[0]}-{radius_m[1]} m")
                for name, (porosity, radius_m) in VARIANTS.items()}
    # The report describes each setting by its registered name; the variants exist only in this probe.
    report_module.SETTINGS = {**SETTINGS, **settings}
    for name, (porosity, radius_m) in VARIANTS.items():
        foliage.CROWN_POROSITY, foliage.CLUSTER_RADIUS_M = porosity, radius_m
        setting = settings[name]
        plan = BenchmarkPlan((setting,), ("town07",), draws, ("coco", "yolo"))
        rows += run_benchmark(plan, workers=1)
        config = with_overrides(SimConfig(), {
            "scenario": {"town": "town07", "placement": "standard", "seed": 0, "foliage": "clusters"},
            "perception": {"kind": "yolo", "yolo_precision": "auto"}, "policy": {"name": "baseline"}})
        loop = ClosedLoop(config)
        clusters = sum(len(foliage.leaf_clusters(crown, foliage.crown_rng(0, geom.name.removesuffix(foliage.CROWN_SUFFIX))).scales)
                       for geom, crown in foliage.crown_envelopes(_solid_spec()))
        result = loop.run()
        loop.close()
        outcomes.append(f"{name}: {clusters} clusters in Town07; {result.outcome}, sign margin {result.sign_margin_m:.1f} m, "
                        f"braking began {result.dist_at_brake_m} m before the sign, first detection "
                        f"{result.first_detection_dist_m} m")
        print(outcomes[-1], flush=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / "frames.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    (out / "report.md").write_text(report(rows, 0.5) + "\n## Closed loop, seed 0\n\n" + "\n".join(f"- {o}" for o in outcomes) + "\n")
    write_figure(rows, out / "recall.png")
    print("\n".join(outcomes))


def _solid_spec():
    """Town07's scene with its solid crowns (the envelopes the clusters fill)."""
    return compose_scene(with_overrides(SimConfig(), {"scenario": {"town": "town07"}}))[0]


if __name__ == "__main__":
    main(int(sys.argv[1]), Path(sys.argv[2]))
