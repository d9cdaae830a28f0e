"""One-off probe: what each camera saw along one run of an experiment file, under the default renders
or one of `avsim realism`'s settings. It replays the run (cell, seed) and prints where braking began,
the outcome, and per 10-m bin of the bumper's distance to the sign: for each camera, how many frames
had a stop-sign box at or above the policy's threshold, and the highest stop-sign score. A policy acts
on a box only inside its braking gate (`policy.trigger_dist_m`, on its own pinhole estimate), so a
confident box far out does not brake the car.

    MUJOCO_GL=egl python experiments/probes/run_trace.py table2_attacked_defended "Town10 far" 3 textured_sheeting_clusters_shadows

Measured here: docs/realism_closed_loop.md, "Table III under the scene settings" (Table II's run that never braked).
It is not part of avsim; it writes nothing.
"""

import sys

from avsim.config import with_overrides
from avsim.control.policy_base import STOP_CLASS
from avsim.experiments.reproduce import EXPERIMENTS_DIR, load_study, specs_for
from avsim.loop import ClosedLoop
from avsim.realism.settings import SETTINGS

BIN_M = 10


def trace(experiment: str, cell: str, seed: int, setting: str) -> None:
    specs = [s for s in specs_for(load_study([EXPERIMENTS_DIR / f"{experiment}.toml"])) if s.cell == cell and s.seed == seed]
    if not specs:
        sys.exit(f"error: {experiment} has no cell {cell!r} with seed {seed}; give a cell and seed of the file")
    config = with_overrides(specs[0].config, SETTINGS[setting].config_overrides())
    loop = ClosedLoop(config)
    threshold = loop.config.policy.conf_threshold
    steps = []  # (bumper to sign [m], {camera: highest stop-sign score})
    while not loop.done():
        detections = loop.perceive(loop.policy.cameras)
        sign_dist_m = loop.scene.stop_sign.base_pos_m[0] - float(loop.vehicle.front_bumper_xy_m()[0])
        best = {camera: max((d.confidence for d in dets if d.class_name == STOP_CLASS), default=0.0)
                for camera, dets in detections.items()}
        braking_before = loop.braking
        record = loop.step_with(detections)
        steps.append((sign_dist_m, best))
        if not braking_before and record.brake > 0:
            print(f"braking began {sign_dist_m:.1f} m before the sign; highest scores "
                  + ", ".join(f"{c} {s:.3f}" for c, s in best.items()))
    result = loop.result(loop.stopped)
    loop.close()
    print(f"{experiment}, {cell}, seed {seed}, {setting}: {result.outcome}, {result.margin_m:.2f} m before the stop line")
    cameras = sorted(steps[0][1])
    print(f"bumper to sign [m]  " + "  ".join(f"{c}: frames >= {threshold} of all, highest score" for c in cameras))
    for low in range(0, int(max(d for d, _ in steps)) + BIN_M, BIN_M):
        in_bin = [best for d, best in steps if low <= d < low + BIN_M]
        if in_bin:
            print(f"{low:4d}-{low + BIN_M:<4d}           " + "  ".join(
                f"{c}: {sum(b[c] >= threshold for b in in_bin):2d} of {len(in_bin):2d}, {max(b[c] for b in in_bin):.3f}"
                for c in cameras))


if __name__ == "__main__":
    trace(sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4] if len(sys.argv) > 4 else "baseline")
