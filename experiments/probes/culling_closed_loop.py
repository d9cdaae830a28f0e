"""One-off probe: what a render saving that keeps every pixel saves in a whole closed-loop run.

Two such savings can be switched off for a check: `--saving cull` (`avsim/sensors/culling.py` drops
the geoms whose bounding sphere lies wholly outside the camera's view before a render;
`tests/sensors/test_culling.py`) and `--saving stencil` (a region read back alone is shaded alone,
`OffscreenRenderer._rasterise_only`; `tests/sensors/test_gl.py`). This probe runs one study run
(85 km/h from 150 m, sensor noise, the own detector or the oracle) alternately with and without the
saving in one process and prints each run's CPU time and whether the two results are identical:

    MUJOCO_GL=egl LP_NUM_THREADS=1 python experiments/probes/culling_closed_loop.py --town town10 --runs 5
    MUJOCO_GL=egl LP_NUM_THREADS=1 python experiments/probes/culling_closed_loop.py --saving stencil --perception oracle

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


# --saving -> the renderer attribute that switches it.
SAVINGS = {"cull": "cull", "stencil": "rasterise_region_only"}


def run_once(config: SimConfig, attribute: str, on: bool) -> tuple[str, float]:
    """One run with the renderers' `attribute` on or off: (its result as canonical JSON, its CPU time [s])."""
    build = gl.OffscreenRenderer.__init__

    def init(self, *args, **kwargs):
        build(self, *args, **kwargs)
        setattr(self, attribute, on)

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
    parser.add_argument("--saving", choices=sorted(SAVINGS), default="cull")
    parser.add_argument("--perception", choices=("detector", "oracle"), default="detector")
    args = parser.parse_args()
    config = with_overrides(SimConfig(), {
        "scenario": {"town": args.town, "placement": "standard", "speed_kmh": 85, "start_speed_kmh": 85,
                     "start_dist_m": 150},
        "perception": {"kind": args.perception, "sensor_noise_std": 2.0}, "policy": {"name": args.policy}})
    results: dict[bool, set[str]] = {False: set(), True: set()}
    cpu_s: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(args.runs):
        for on in (False, True):
            result, seconds = run_once(config, SAVINGS[args.saving], on)
            results[on].add(result)
            cpu_s[on].append(seconds)
    for on in (False, True):
        later = cpu_s[on][1:] or cpu_s[on]
        print(f"{args.town} {args.policy} {args.perception} {args.saving} {'on ' if on else 'off'}: CPU per run "
              f"{', '.join(f'{s:.2f}' for s in cpu_s[on])} s; median after the first {statistics.median(later):.2f} s")
    print("results identical:", len(results[False]) == 1 and results[False] == results[True])


if __name__ == "__main__":
    main()
