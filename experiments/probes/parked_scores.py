"""One-off probe: a network's highest stop-sign score on one camera, with the car parked at a row of distances,
under the default renders and one of `avsim realism`'s settings, paired frame for frame.

A closed-loop run answers "did the car stop"; when a render setting moves that answer, this asks why, without
the loop. For each seed of one cell of an experiment file (the seed draws the cell's lighting), the car is
placed at rest with its bumper `start_dist_m` from the stop line, one frame is rendered per camera and
perceived, and the highest stop-sign score is kept. The same poses and lighting are rendered under
both settings, so each pair of scores differs by the render alone. It prints, per 1-m distance, the mean
score under each setting over the seeds, the mean paired difference, how many pairs the setting lowers, and how
many frames reach the policy's threshold under each; then the same per 5-m band of the bumper's distance:

    MUJOCO_GL=egl python experiments/probes/parked_scores.py attacks/success_coco_towns "driveby_detector, coco, Town03 far" window_geometry --dist-m 30:45

Measured here: docs/realism_filtering.md, "Measured: why Town03 far, the windows near the braking edge".
It is not part of avsim; it writes nothing.
"""

from __future__ import annotations

import argparse
import statistics

from avsim.config import with_overrides
from avsim.control.policy_base import STOP_CLASS
from avsim.experiments.reproduce import EXPERIMENTS_DIR, load_study, specs_for
from avsim.loop import ClosedLoop
from avsim.realism.settings import SETTINGS

BAND_M = 5


def parked_score(config, setting: str, start_dist_m: float, camera: str) -> tuple[float, float]:
    """(bumper to the sign [m], the highest stop-sign score on `camera`, 0 without a box) of one frame with
    the car at rest `start_dist_m` [m] before the stop line, under `setting`."""
    config = with_overrides(config, SETTINGS[setting].config_overrides())
    config = with_overrides(config, {"scenario": {"start_dist_m": start_dist_m, "start_speed_kmh": 0.0}})
    loop = ClosedLoop(config)
    try:
        detections = loop.perceive((camera,))[camera]
        bumper_to_sign_m = loop.scene.stop_sign.base_pos_m[0] - float(loop.vehicle.front_bumper_xy_m()[0])
        return bumper_to_sign_m, max((d.confidence for d in detections if d.class_name == STOP_CLASS), default=0.0)
    finally:
        loop.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("experiment", help="experiment file under experiments/, without .toml")
    parser.add_argument("cell")
    parser.add_argument("setting", help="the realism setting compared with the default renders (baseline)")
    parser.add_argument("--dist-m", default="30:45", help="first:last start distance to the stop line [m], 1-m steps")
    parser.add_argument("--camera", default="front")
    args = parser.parse_args()
    if args.setting not in SETTINGS:
        parser.error(f"unknown setting {args.setting!r}; choose from {', '.join(SETTINGS)}")
    first_m, last_m = (int(v) for v in args.dist_m.split(":"))
    specs = [s for s in specs_for(load_study([EXPERIMENTS_DIR / f"{args.experiment}.toml"])) if s.cell == args.cell]
    if not specs:
        parser.error(f"{args.experiment} has no cell {args.cell!r}")
    threshold = specs[0].config.policy.conf_threshold
    frames = []  # (start distance [m], bumper to sign [m], baseline score, setting score), every seed and distance
    for start_dist_m in range(first_m, last_m + 1):
        for spec in specs:
            bumper_m, base = parked_score(spec.config, "baseline", float(start_dist_m), args.camera)
            _, other = parked_score(spec.config, args.setting, float(start_dist_m), args.camera)
            frames.append((start_dist_m, bumper_m, base, other))
    print(f"{args.cell}, {len(specs)} seeds, {args.camera} camera: baseline against {args.setting}")
    print("each row: frames, mean score baseline / setting, mean paired difference, pairs the setting lowers, "
          "frames >= threshold baseline / setting")
    print("per start distance, at the mean bumper-to-sign distance [m]:")
    for start_dist_m in range(first_m, last_m + 1):
        rows = [f for f in frames if f[0] == start_dist_m]
        print(f"{statistics.mean(f[1] for f in rows):6.1f} m: {_summary(rows, threshold)}")
    print(f"per {BAND_M}-m band of the bumper's distance to the sign:")
    for low_m in range(int(min(f[1] for f in frames)) // BAND_M * BAND_M, int(max(f[1] for f in frames)) + 1, BAND_M):
        band = [f for f in frames if low_m <= f[1] < low_m + BAND_M]
        if band:
            print(f"{low_m}-{low_m + BAND_M} m: {_summary(band, threshold)}")


def _summary(rows: list[tuple[int, float, float, float]], threshold: float) -> str:
    """One printed row over `rows` of (start distance, bumper distance, baseline score, setting score)."""
    base, other = [r[2] for r in rows], [r[3] for r in rows]
    return (f"{len(rows)}, {statistics.mean(base):.3f} / {statistics.mean(other):.3f}, "
            f"{statistics.mean(o - b for b, o in zip(base, other)):+.3f}, {sum(o < b for b, o in zip(base, other))}, "
            f"{sum(b >= threshold for b in base)} / {sum(o >= threshold for o in other)}")

if __name__ == "__main__":
    main()
