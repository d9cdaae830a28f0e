"""Renders the reference tests run both sides on: 3 towns x 7 views, both cameras, 6-40 m.

Shared by the COCO CenterNet's TF.js reference, the NanoDet interpreter's and the YOLO reader's
OpenCV reference, so the ports are checked on the same pixels (the COCO one on seven of them).
"""

from __future__ import annotations

import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.towns import TOWNS

# (placement, camera, bumper-to-stop-line distance [m], lateral offset [m], yaw [deg]) per town.
VIEWS = (
    ("near", "front", 10.0, 0.0, 0.0),
    ("standard", "front", 25.0, 0.0, 0.0),
    ("far", "front", 40.0, 0.0, 0.0),
    ("standard", "front", 30.0, 1.5, 3.0),
    ("standard", "side", 6.0, 0.0, 0.0),
    ("far", "side", 14.0, 0.0, 0.0),
    ("near", "side", 18.0, -0.5, -4.0),
)


def one_of_each_view(frames: list[tuple[str, np.ndarray]]) -> list[tuple[str, np.ndarray]]:
    """Seven of render_views' frames, each view once: a town's k-th frame from the k-th town in turn."""
    towns = TOWNS.names()
    assert len(frames) == len(towns) * len(VIEWS)
    return [frames[(k % len(towns)) * len(VIEWS) + k] for k in range(len(VIEWS))]


def render_views() -> list[tuple[str, np.ndarray]]:
    """(name "town/placement/camera/distance", (480, 640, 3) uint8 RGB frame) for every town and view."""
    frames = []
    for town in TOWNS.names():
        for placement in ("near", "standard", "far"):
            views = [v for v in VIEWS if v[0] == placement]
            loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town, "placement": placement},
                                                             "perception": {"kind": "oracle"}}))
            try:
                for _, camera, dist_m, offset_m, yaw_deg in views:
                    loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M,
                                       loop.scene.layout.lane_center_y_m + offset_m, np.radians(yaw_deg), 0.0)
                    frames.append((f"{town}/{placement}/{camera}/{dist_m:g}m", loop.rig.render_rgb(loop.data, camera)))
            finally:
                loop.close()
    return frames
