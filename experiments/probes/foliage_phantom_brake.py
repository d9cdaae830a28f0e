"""One-off probe: what opens the braking gate under YOLOv3-tiny in Town07 standard, with solid and with
see-through tree crowns (`scenario.foliage`). Each run is `avsim run --town town07 --placement standard
--perception yolo --set perception.yolo_precision=auto --seed SEED --set scenario.foliage=FOLIAGE`
(baseline policy, clean sign). At the first step whose command brakes, it prints each confident
stop-sign box (score >= policy.conf_threshold), its height, the pinhole range the policy reads from it,
and what the box sits on: the geom most common in the middle ninth of the box, from a segmentation render
of that camera at the same state (named without copy numbers, as `avsim realism` names them).

    MUJOCO_GL=egl nice -n 5 python experiments/probes/foliage_phantom_brake.py 0,1,2 solid,clusters

Measured here: docs/realism_foliage.md, "See-through tree crowns".
"""

import sys

from avsim.config import SimConfig, with_overrides
from avsim.control.policy_base import STOP_CLASS
from avsim.loop import ClosedLoop
from avsim.realism.scoring import geom_under_box


def _sits_on(loop: ClosedLoop, camera: str, box_xyxy_px) -> str:
    """What `box_xyxy_px` (RGB-image pixels) sits on, from a segmentation render at the loop's state."""
    ids = loop.rig.render_segmentation(loop.data, camera)
    return geom_under_box(loop.model, ids, loop.config.camera.height_px, box_xyxy_px)


def main(seeds: list[int], foliages: list[str]) -> None:
    for foliage in foliages:
        for seed in seeds:
            config = with_overrides(SimConfig(), {
                "scenario": {"town": "town07", "placement": "standard", "seed": seed, "foliage": foliage},
                "perception": {"kind": "yolo", "yolo_precision": "auto"}, "policy": {"name": "baseline"}})
            loop = ClosedLoop(config)
            gate = None
            while not loop.done():
                detections = loop.perceive(loop.policy.cameras)
                if gate is None:
                    # Label the boxes at the state they were seen in, before the step moves the car.
                    sign_dist_m = loop.scene.stop_sign.base_pos_m[0] - float(loop.vehicle.front_bumper_xy_m()[0])
                    labels = [(camera, d, _sits_on(loop, camera, d.box_xyxy_px)) for camera, dets in detections.items()
                              for d in dets if d.class_name == STOP_CLASS and d.confidence >= config.policy.conf_threshold]
                record = loop.step_with(detections)
                if gate is None and record.brake > 0:  # the policy brakes on a range estimate, so it has one
                    gate = (sign_dist_m, record.est_stop_line_dist_m, labels)
            result = loop.result(loop.stopped)
            loop.close()
            sign_dist_m, estimate_m, labels = gate if gate else (None, None, [])
            print(f"{foliage:8s} seed {seed}: {result.outcome}, sign margin {result.sign_margin_m:.1f} m; braking began "
                  f"{sign_dist_m:.1f} m before the sign (the policy's stop-line estimate {estimate_m:.1f} m)"
                  if gate else f"{foliage:8s} seed {seed}: {result.outcome}, never braked", flush=True)
            for camera, d, label in labels:
                x0, y0, x1, y1 = d.box_xyxy_px
                print(f"    {camera} box {y1 - y0:.0f} px tall at {d.confidence:.2f}, on {label}", flush=True)


if __name__ == "__main__":
    main([int(s) for s in sys.argv[1].split(",")], sys.argv[2].split(","))
