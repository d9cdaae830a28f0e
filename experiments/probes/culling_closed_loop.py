"""One-off probe: what leaving out-of-view geoms out of each render saves in a whole closed-loop run.

`avsim/sensors/culling.py` drops the geoms whose bounding sphere lies wholly outside the camera's
view before a render; `tests/sensors/test_culling.py` checks that the pixels are the same. This
probe runs one study run (85 km/h from 150 m, sensor noise, the own detector) alternately with
and without culling in one process and prints each run's CPU time and whether the two results are
identical:

    MUJOCO_GL=egl LP_NUM_THREADS=1 python experiments/probes/culling_closed_loop.py --town town10 --runs 5

The first run of each kind pays for the process's warm-up (torch, the GL context's shaders), so
compare the later ones. It is not part of avsim; it writes nothing.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from avsim.config import SimConfig, with_overrides
from avsim.runner import run_config
from avsim.sensors import gl


def run_once(config: SimConfig, cull: bool) -> tuple[str, float]:
    """One run with culling on or off: (its result as canonical JSON, its CPU time [s])."""
    build = gl.OffscreenRenderer.__init__

    def init(self, *args, **kwargs):
        build(self, *args, **{**kwargs, "cull": cull})

    gl.OffscreenRenderer.__init__ = init
    try:
        started = time.process_time()
        result, _ = run_config(config)
        return json.dumps(result.to_json_dict(), sort_keys=True), time.process_time() - started
    finally:
        gl.OffscreenRenderer.__init__ = build


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--town", default="town07")
    parser.add_argument("--policy", default="baseline", help="baseline (front camera) or side_camera (both)")
    parser.add_argument("--runs", type=int, default=5, help="runs of each kind, alternating")
    args = parser.parse_args()
    config = with_overrides(SimConfig(), {
        "scenario": {"town": args.town, "placement": "standard", "speed_kmh": 85, "start_speed_kmh": 85,
                     "start_dist_m": 150},
        "perception": {"kind": "detector", "sensor_noise_std": 2.0}, "policy": {"name": args.policy}})
    results: dict[bool, set[str]] = {False: set(), True: set()}
    cpu_s: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(args.runs):
        for cull in (False, True):
            result, seconds = run_once(config, cull)
            results[cull].add(result)
            cpu_s[cull].append(seconds)
    for cull in (False, True):
        later = cpu_s[cull][1:] or cpu_s[cull]
        print(f"{args.town} {args.policy} culling {'on ' if cull else 'off'}: CPU per run "
              f"{', '.join(f'{s:.2f}' for s in cpu_s[cull])} s; median after the first {statistics.median(later):.2f} s")
    print("results identical:", len(results[False]) == 1 and results[False] == results[True])


if __name__ == "__main__":
    main()
