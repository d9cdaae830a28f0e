"""Camera snapshots: what the car sees at a given distance from the stop line, one town or several side by side."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.outputs import write_image
from avsim.sensors.camera import CAMERA_NAMES
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.road import APPROACH_LENGTH_M, ROAD_END_X_M

# Front bumper to stop line [m]: the whole car must stand on the road, which runs from
# APPROACH_LENGTH_M before the line to ROAD_END_X_M past it (negative: past the line).
SNAPSHOT_DIST_RANGE_M = (-(ROAD_END_X_M - 20.0), APPROACH_LENGTH_M - 20.0)


def check_snapshot_distance(bumper_to_stop_line_m: float) -> None:
    """A one-line ConfigError unless the distance is finite and puts the car on the road."""
    low, high = SNAPSHOT_DIST_RANGE_M
    if not (math.isfinite(bumper_to_stop_line_m) and low <= bumper_to_stop_line_m <= high):
        raise ConfigError(f"--dist-m must be in [{low:g}, {high:g}] m (front bumper to stop line; negative: past it), "
                          f"got {bumper_to_stop_line_m}")


def camera_views(config: SimConfig, bumper_to_stop_line_m: float) -> dict[str, np.ndarray]:
    """Each camera's (H, W, 3) BGR image with the car at rest `bumper_to_stop_line_m` before the
    stop line, with the configured perception's boxes and scores drawn."""
    check_snapshot_distance(bumper_to_stop_line_m)
    loop = ClosedLoop(config)
    try:
        loop.vehicle.place(loop.scene.stop_line_x_m - bumper_to_stop_line_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        views = {}
        for camera in CAMERA_NAMES:
            image = loop.rig.render_rgb(loop.data, camera)[..., ::-1].copy()  # BGR for OpenCV
            for det in loop.perception.detect(loop.rig, loop.data, camera):
                x0, y0, x1, y1 = (int(round(v)) for v in det.box_xyxy_px)
                cv2.rectangle(image, (x0, y0), (x1, y1), (0, 255, 0), 1)
                cv2.putText(image, f"{det.class_name} {det.confidence:.2f}", (x0, max(y0 - 4, 10)),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 255, 0), 1, cv2.LINE_AA)
            views[camera] = image
        return views
    finally:
        loop.close()


def save_snapshot(config: SimConfig, bumper_to_stop_line_m: float, out_prefix: str) -> list[Path]:
    """Save `{out_prefix}_{camera}.png` for each camera (see `camera_views`)."""
    views = camera_views(config, bumper_to_stop_line_m)
    return [write_image(f"{out_prefix}_{camera}.png", image) for camera, image in views.items()]


def save_town_strip(config: SimConfig, towns: list[str], bumper_to_stop_line_m: float, out_prefix: str) -> Path:
    """Save `{out_prefix}.png`: the front camera of each town side by side, each at half size
    (the README's picture of the towns, docs/towns_front.png)."""
    tiles = []
    for town in towns:
        front = camera_views(with_overrides(config, {"scenario": {"town": town}}), bumper_to_stop_line_m)["front"]
        tiles.append(cv2.resize(front, (front.shape[1] // 2, front.shape[0] // 2), interpolation=cv2.INTER_AREA))
    return write_image(f"{out_prefix}.png", np.hstack(tiles))
