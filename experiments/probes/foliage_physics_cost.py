"""One-off probe: what see-through crowns (`scenario.foliage`) cost the physics and the scene build.

For Town07 with solid and with cluster crowns it prints the CPU time (`time.process_time`) of building
the scene and of one `mj_step` (the car placed 200 m before the line at 10 m/s, 50 steps to settle, then
2,000 steps timed, twice), and MuJoCo's geom count.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/foliage_physics_cost.py

Measured here: docs/realism_foliage.md, "See-through tree crowns".
"""

import time

import mujoco

from avsim.config import SimConfig, with_overrides
from avsim.vehicle.physics import Vehicle
from avsim.world.scene import build_scene

TIMED_STEPS = 2000


def main() -> None:
    for repeat in range(2):
        for foliage in ("solid", "clusters"):
            config = with_overrides(SimConfig(), {"scenario": {"town": "town07", "foliage": foliage}})
            start_s = time.process_time()
            model, info = build_scene(config)
            build_s = time.process_time() - start_s
            data = mujoco.MjData(model)
            Vehicle(model, data, config.vehicle).place(-200.0, info.layout.lane_center_y_m, 0.0, 10.0)
            for _ in range(50):
                mujoco.mj_step(model, data)
            start_s = time.process_time()
            for _ in range(TIMED_STEPS):
                mujoco.mj_step(model, data)
            step_us = (time.process_time() - start_s) / TIMED_STEPS * 1e6
            print(f"repeat {repeat} {foliage:8s} geoms {model.ngeom}  build {build_s:.2f} s CPU  mj_step {step_us:.1f} us CPU",
                  flush=True)


if __name__ == "__main__":
    main()
