"""One-off probe: what leaving out the oracle's far frames saves, and that it changes nothing.

The `oracle` perception renders a 2x supersampled segmentation (1280x960) to find each sign's box, and llvmpipe
pays about 8 ms a frame for a framebuffer that size even with nothing drawn (it clears and stores every tile).
Since 2026-12-02 a sign whose projected outline cannot reach the oracle's range height (6.8 px) is not rendered
(`CameraRig.sign_boxes`' min_height_px); with no sign left, nothing is. This probe runs oracle study runs (85 km/h
from rest, 230 m out) both ways in one process, alternately: as shipped, and with the slack set to infinity, which
renders every frame as before. It prints each run's CPU time, its segmentation renders, and whether the result and
every per-step record are the same:

    MUJOCO_GL=egl python experiments/probes/oracle_far_frames.py

It is not part of avsim; it writes nothing. About two minutes.
"""

from __future__ import annotations

import hashlib
import json
import math
import time

import mujoco

from avsim.config import SimConfig, with_overrides
from avsim.runner import run_recorded
from avsim.sensors import camera, gl

CELLS = (("town07", "standard", "baseline"), ("town03", "standard", "baseline"), ("town10", "standard", "baseline"),
         ("town07", "far", "side_camera"))
SHIPPED_SLACK = camera.SMALLEST_BOX_SLACK_SEG_PX


def _counting_renders() -> list[int]:
    """Wraps OffscreenRenderer.render to count segmentation renders; returns the one-element counter."""
    count = [0]
    real = gl.OffscreenRenderer.render

    def render(self, *args, **kwargs):
        count[0] += int(self._scene.flags[int(mujoco.mjtRndFlag.mjRND_SEGMENT)])
        return real(self, *args, **kwargs)

    gl.OffscreenRenderer.render = render
    return count


def _run(config: SimConfig, slack: float, renders: list[int]) -> tuple[float, int, str]:
    """(CPU seconds, segmentation renders, a hash of the result and the records) of one run at `slack`."""
    camera.SMALLEST_BOX_SLACK_SEG_PX = slack
    renders[0] = 0
    start = time.process_time()
    output = run_recorded(config)
    cpu_s = time.process_time() - start
    blob = json.dumps([output.result.to_json_dict(), [repr(r) for r in output.records]], sort_keys=True, default=str)
    return cpu_s, renders[0], hashlib.sha256(blob.encode()).hexdigest()


def main() -> None:
    renders = _counting_renders()
    run_recorded(with_overrides(SimConfig(), {"perception": {"kind": "oracle"}, "scenario": {"start_dist_m": 60.0}}))  # warm-up
    for town, placement, policy in CELLS:
        config = with_overrides(SimConfig(), {"scenario": {"town": town, "placement": placement},
                                              "policy": {"name": policy}, "perception": {"kind": "oracle"}})
        every = _run(config, math.inf, renders)
        shipped = _run(config, SHIPPED_SLACK, renders)
        print(f"{town} {placement} {policy}: every frame {every[0]:.2f} CPU-s ({every[1]} segmentation renders), "
              f"far frames left out {shipped[0]:.2f} CPU-s ({shipped[1]}); "
              f"{'the same result and records' if every[2] == shipped[2] else 'RESULTS DIFFER'}", flush=True)


if __name__ == "__main__":
    main()
