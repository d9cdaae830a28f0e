"""One-off probe: does the COCO CenterNet miss Town10's stop sign because of what stands behind it? In
Town10 the sign is seen against a brick facade (`facade_brick`: a red-brown wall) from about 45 m, and under
`--perception coco` the first confident detection comes 27-41 m out under every scene of
experiments/coco_detector_realism.toml. This replays runs of that file under backdrops:

- `brick`: as they are;
- `concrete`: every brick facade given the concrete facade's material (`facade_concrete`: a grey wall with
  the same windows);
- `none`: no facade at all (every geom with a facade material left out of the render), so that the sign
  stands against the sky, as it does in Town07;

the sign, the light and everything else unchanged. These are counterfactuals about the scene, not realism
settings: the towns keep their buildings.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/town10_backdrop.py "Town10 standard, baseline, flat" 0,1,2,3,4 brick,concrete,none

For each seed and backdrop: where the first confident stop-sign detection came (bumper to sign), where
braking began, and whether the car stopped before the sign.

Measured here: docs/realism_closed_loop.md, "The COCO closed loop in Town10 under the realism settings".
"""

import sys
from pathlib import Path

import numpy as np

from avsim.experiments import load_experiment
from avsim.loop import ClosedLoop

EXPERIMENT = Path(__file__).resolve().parents[1] / "coco_detector_realism.toml"


BACKDROPS = ("brick", "concrete", "none")


def _run(config, backdrop: str) -> str:
    loop = ClosedLoop(config)
    model = loop.model  # every render reads the geoms' materials and colours from it afresh
    if backdrop == "concrete":
        model.geom_matid[model.geom_matid == model.material("facade_brick").id] = model.material("facade_concrete").id
    elif backdrop == "none":
        facades = [i for i in range(model.nmat) if model.material(i).name.startswith("facade_")]
        hidden = np.isin(model.geom_matid, facades)
        model.geom_matid[hidden] = -1
        model.geom_rgba[hidden, 3] = 0.0  # a geom of alpha 0 is left out of the scene
    result = loop.run()
    loop.close()
    first = "never" if result.first_detection_dist_m is None else f"{result.first_detection_dist_m:5.1f} m"
    brake = "never" if result.dist_at_brake_m is None else f"{result.dist_at_brake_m:5.1f} m"
    stopped = "stopped before the sign" if result.sign_margin_m > 0 else "ran past the sign"
    return f"first detection {first}, braking from {brake}, {stopped} ({result.sign_margin_m:+.1f} m)"


def main(cell: str, seeds: list[int], backdrops: list[str]) -> None:
    runs = {(run.cell_name, run.seed): run.config for run in load_experiment(EXPERIMENT).runs()}
    for seed in seeds:
        print(f"{cell}, seed {seed}:", flush=True)
        for backdrop in backdrops:
            print(f"  {backdrop:8s} {_run(runs[(cell, seed)], backdrop)}", flush=True)


if __name__ == "__main__":
    chosen = sys.argv[3].split(",") if len(sys.argv) > 3 else list(BACKDROPS)
    if set(chosen) - set(BACKDROPS):
        sys.exit(f"error: unknown backdrop {sorted(set(chosen) - set(BACKDROPS))[0]!r}; choose from {', '.join(BACKDROPS)}")
    main(sys.argv[1], [int(s) for s in sys.argv[2].split(",")], chosen)
