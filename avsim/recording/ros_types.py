"""ROS 2 message types for avsim's bags: rosbags' bundled Humble type store, plus the vendored
`vision_msgs` and `ackermann_msgs` definitions (`ros_msgs/`, with their licences).

    store = typestore()                      # needs avsim[ros]; a one-line ConfigError without it
    store.types["sensor_msgs/msg/CameraInfo"]

Frames (REP 103: x forward, y left, z up; REP 105: map -> odom -> base_link):
    map                      avsim's world frame: x along the road towards the stop line, y left, z up [m]
    odom                     the same as map (the car's pose is ground truth, so odometry never drifts)
    base_link                the car body: x forward, y left, z up, origin midway between the axles
                             at wheel-centre height
    <camera>_camera_link     the camera's mount in the body (x forward, y left, z up)
    <camera>_camera_optical_frame  the same point, optical axes: z forward, x right, y down (REP 103);
                             images, camera_info and detections are in it
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from avsim.errors import ConfigError

INSTALL_HINT = "pip install 'avsim[ros]' (or make, which installs it)"
ROS_MSGS_DIR = Path(__file__).resolve().parent / "ros_msgs"
VENDORED = {
    "vision_msgs": ("Point2D", "Pose2D", "BoundingBox2D", "ObjectHypothesis", "ObjectHypothesisWithPose",
                    "Detection2D", "Detection2DArray"),
    "ackermann_msgs": ("AckermannDrive", "AckermannDriveStamped"),
}
MAP_FRAME, ODOM_FRAME, BASE_FRAME = "map", "odom", "base_link"


def camera_link(camera: str) -> str:
    """TF frame of a camera's mount on the car ("front_camera_link"): x forward, y left, z up."""
    return f"{camera}_camera_link"


def optical_frame(camera: str) -> str:
    """TF frame of a camera's image ("front_camera_optical_frame"): x right, y down, z forward (REP 103)."""
    return f"{camera}_camera_optical_frame"


def require_rosbags() -> Any:
    """The `rosbags` package, or a one-line ConfigError naming the extra that installs it."""
    try:
        import rosbags.rosbag2  # noqa: F401 - the writer and reader live there
        import rosbags.typesys
    except ImportError:
        raise ConfigError(f"ROS 2 bags (--mcap, replay) need the ros extra, which is not installed: {INSTALL_HINT}") from None
    return rosbags


@functools.cache
def typestore() -> Any:
    """rosbags' ROS 2 Humble type store with the vendored message packages registered."""
    require_rosbags()
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    for package, names in VENDORED.items():
        for name in names:
            text = (ROS_MSGS_DIR / package / "msg" / f"{name}.msg").read_text()
            types.update(get_types_from_msg(text, f"{package}/msg/{name}"))
    store.register(types)
    return store


def stamp(time_s: float) -> Any:
    """builtin_interfaces/Time of a simulated time [s], to the nanosecond."""
    ns = time_ns(time_s)
    return typestore().types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def time_ns(time_s: float) -> int:
    """Simulated time [s] as integer nanoseconds, the bag's message timestamps."""
    return round(time_s * 1e9)


def header(time_s: float, frame_id: str) -> Any:
    """A std_msgs/Header stamped at simulated `time_s` [s] in `frame_id`."""
    return typestore().types["std_msgs/msg/Header"](stamp=stamp(time_s), frame_id=frame_id)
