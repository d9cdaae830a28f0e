"""One-off probe: a default closed-loop run (town07, standard placement, clean sign, baseline
policy, seed 0) under each camera preset, per perception: its outcome and its CPU time per
control step (`time.process_time`: rendering both cameras, Mesa's GL threads and the networks).

    MUJOCO_GL=egl nice -n 5 python experiments/probes/camera_preset_smoke.py detector,coco study,automotive_1080p

Measured here (2 cores shared with other jobs; docs/realism_camera.md, "Camera presets"):
detector study 22.0 ms/step, automotive_1080p 56.6 ms; coco study 65.4 ms, automotive_1080p 568.4 ms.
With the own detector's native pass (perception.detector_native_pixels, the default since): detector
study 19.9 ms, automotive_1080p 99.0 ms (`camera_preset_smoke.py detector study,automotive_1080p`).
"""

import sys
import time

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop


def main(perceptions: list[str], presets: list[str]) -> None:
    for perception in perceptions:
        for preset in presets:
            config = with_overrides(SimConfig(), {"camera": {"preset": preset}, "perception": {"kind": perception}})
            loop = ClosedLoop(config)
            start_s = time.process_time()
            result = loop.run()
            cpu_s = time.process_time() - start_s
            steps = len(loop.records)
            loop.close()
            print(f"{perception:9s} {preset:17s} outcome={result.outcome} margin_m={result.margin_m:.2f} "
                  f"first_detection_m={result.first_detection_dist_m} brake_at_m={result.dist_at_brake_m} "
                  f"steps={steps} cpu_ms_per_step={1e3 * cpu_s / steps:.1f}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1].split(","), sys.argv[2].split(","))
