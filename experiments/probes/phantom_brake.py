"""One-off probe: what made a recorded run brake. It replays a run of a results file (`runs.jsonl` of
`avsim reproduce`, `results.jsonl` of `avsim leaderboard`) from the config stored with it, checks that
the replay ends where the record says, and prints, at the first step whose command brakes and at every
step before it that had a confident stop-sign box anywhere but on the stop sign:

- the sign's true distance and the policy's stop-line estimate at that step;
- each confident stop-sign box (score >= policy.conf_threshold): its camera, the network that gave it
  (`Detection.source`; the ensemble tags each member's box), its height, its score, and what it sits on
  (the geom most common in the middle ninth of the box, from a segmentation render of that camera at the
  same state, named as `avsim realism` names them), and how much of the stop sign's visible face it covers
  (`avsim realism`'s "over a sign": the fraction of the sign's box inside it; 0 for a box apart from the sign).

    MUJOCO_GL=egl nice -n 5 python experiments/probes/phantom_brake.py RESULTS.jsonl "CELL" 1,2,3

Measured here: docs/realism_foliage.md, "The COCO CenterNet's phantom with see-through crowns".
"""

import json
import sys

import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.control.policy_base import STOP_CLASS
from avsim.loop import ClosedLoop
from avsim.realism.scoring import geom_under_box, sign_cover


def _recorded_run(results_path: str, cell: str, seed: int) -> dict:
    with open(results_path) as rows:
        for line in rows:
            row = json.loads(line)
            if row["cell"] == cell and row["seed"] == seed:
                return row
    sys.exit(f"error: no run of cell {cell!r}, seed {seed} in {results_path}; give a cell and seed the file holds")


def _labelled_boxes(loop: ClosedLoop, detections: dict) -> list[tuple[str, object, str, float, np.ndarray]]:
    """(camera, detection, what it sits on, the fraction of the stop sign's box it covers, that box (1, 4) or
    (0, 4) xyxy [px]) of every confident stop-sign box, one segmentation render a camera."""
    labelled = []
    sign = loop.scene.stop_sign
    face = {"stop_sign": (loop.model.geom(sign.face_geom).id, sign.corners_m())}
    for camera, dets in detections.items():
        confident = [d for d in dets if d.class_name == STOP_CLASS and d.confidence >= loop.config.policy.conf_threshold]
        if confident:
            ids = loop.rig.render_segmentation(loop.data, camera)
            truth = np.asarray(list(loop.rig.sign_boxes(loop.data, camera, face).values()), float).reshape(-1, 4)
            labelled += [(camera, d, geom_under_box(loop.model, ids, loop.config.camera.height_px, d.box_xyxy_px),
                          sign_cover(d.box_xyxy_px, truth), truth) for d in confident]
    return labelled


def _print_step(heading: str, sign_dist_m: float, estimate_m, labelled: list) -> None:
    estimate = "none" if estimate_m is None else f"{estimate_m:.1f} m"
    print(f"  {heading} {sign_dist_m:.1f} m before the sign (the policy's stop-line estimate: {estimate})", flush=True)
    for camera, d, on, cover, truth in labelled:
        x0, y0, x1, y1 = d.box_xyxy_px
        sign = "the sign not in view" if not len(truth) else (
            f"covers {cover:.0%} of the sign's box ({truth[0, 3] - truth[0, 1]:.0f} px tall at "
            f"({(truth[0, 0] + truth[0, 2]) / 2:.0f}, {(truth[0, 1] + truth[0, 3]) / 2:.0f}) px)")
        print(f"    {camera} {d.source or 'network'} box {y1 - y0:.0f} px tall at ({(x0 + x1) / 2:.0f}, "
              f"{(y0 + y1) / 2:.0f}) px, score {d.confidence:.2f}, on {on}; {sign}", flush=True)


def replay(results_path: str, cell: str, seed: int) -> None:
    row = _recorded_run(results_path, cell, seed)
    config = with_overrides(SimConfig(), row["result"]["config"])
    loop = ClosedLoop(config)
    print(f"{cell}, seed {seed}:", flush=True)
    while not loop.done():
        detections = loop.perceive(loop.policy.cameras)
        labelled = _labelled_boxes(loop, detections)
        sign_dist_m = loop.scene.stop_sign.base_pos_m[0] - float(loop.vehicle.front_bumper_xy_m()[0])
        braking_before = loop.braking
        record = loop.step_with(detections)
        if not braking_before and record.brake > 0:
            _print_step("braking began", sign_dist_m, record.est_stop_line_dist_m, labelled)
            break
        if any(on != "stop_sign/face" for _, _, on, _, _ in labelled):
            _print_step("a box off the sign", sign_dist_m, record.est_stop_line_dist_m, labelled)
    while not loop.done():
        loop.step()
    result = loop.result(loop.stopped)
    loop.close()
    recorded_m = row["result"]["margin_m"]  # bumper to stop line
    same = "as recorded" if result.margin_m == recorded_m else f"NOT as recorded ({recorded_m:.2f} m)"
    print(f"  {result.outcome}, {result.margin_m:.2f} m before the stop line at rest, {same}", flush=True)


if __name__ == "__main__":
    for seed in sys.argv[3].split(","):
        replay(sys.argv[1], sys.argv[2], int(seed))
