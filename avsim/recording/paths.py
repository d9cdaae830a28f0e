"""Rerun entity paths and timelines of an avsim recording: the stable names a reader relies on.

World entities are in the MuJoCo world frame (x along the road towards the stop
line, y left, z up; metres). Metric entities are named after `StepRecord` fields,
so `metrics/speed_mps` holds `StepRecord.speed_mps`.
"""

from __future__ import annotations

# Timelines: `frame` is the control-step index (the index into `ClosedLoop.records`);
# `sim_time` is that step's sensing time [s] (`StepRecord.time_s`).
FRAME_TIMELINE = "frame"
SIM_TIME_TIMELINE = "sim_time"

WORLD = "world"
CAR = "world/car"  # Transform3D: car body frame -> world, at sensing time
CAR_BODY = "world/car/body"  # static Boxes3D in the car body frame
TRAJECTORY = "world/trajectory"  # LineStrips3D of body-origin positions so far
STOP_SIGN = "world/stop_sign"  # static outline and post of the stop sign
STOP_LINE = "world/stop_line"  # static line across the travelled lanes
ROAD = "world/road"  # static carriageway edges, for orientation


def camera(name: str) -> str:
    """Transform3D: camera frame (MuJoCo: x right, y up, z back) -> world."""
    return f"world/cameras/{name}"


def camera_image(name: str) -> str:
    """Pinhole (static) and JPEG EncodedImage of the camera."""
    return f"{camera(name)}/image"


def camera_detections(name: str) -> str:
    """Boxes2D in the camera's pixel coordinates, labelled "class confidence"."""
    return f"{camera_image(name)}/detections"


# StepRecord fields logged as scalar series under metrics/<field>. Optional fields
# (None when the policy has no estimate) are skipped at steps where they are None.
METRIC_FIELDS = (
    "speed_mps",
    "throttle",
    "brake",
    "stop_line_dist_m",
    "est_stop_line_dist_m",
    "top_stop_conf",
    "required_decel_mps2",
    "pitch_rad",
    "max_brake_slip",
)


def metric(field: str) -> str:
    """Rerun entity path of one metric's time series ("metrics/speed_mps")."""
    return f"metrics/{field}"
