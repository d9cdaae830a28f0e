"""One-off probe: which library writes avsim's ROS 2 bags, rosbags or mcap + mcap-ros2-support?

Both write the same MCAP file of 300 control steps: one front-camera PNG (40 real renders of a
Town07 approach, repeated) and one nav_msgs/Odometry per step, with and without zstd chunk
compression; the probe prints the write time per step (serialisation included) and the size.
mcap-ros2-support has no bundled message definitions, so its schemas are rosbags' Humble ones.
Needs avsim[ros] and mcap-ros2-support (in the dev extra). Run it on a quiet machine:

    MUJOCO_GL=egl python experiments/probes/ros_bag_writers.py

Measured here (2 cores shared with other jobs, docs/ros.md): rosbags 0.23 ms/step and 15.5 MB,
0.84 ms and 12.5 MB with zstd; mcap + mcap-ros2-support 0.34 ms and 15.5 MB, 1.29 ms and 12.5 MB.
"""
import time, shutil, tempfile, numpy as np, cv2
from pathlib import Path
from rosbags.typesys import Stores, get_typestore
from rosbags.rosbag2 import Writer, StoragePlugin
from rosbags.rosbag2.enums import CompressionMode, CompressionFormat
from mcap_ros2.writer import Writer as MW
from mcap.writer import CompressionType
from avsim.loop import ClosedLoop
from avsim.config import SimConfig, with_overrides
loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": "oracle"}}))
frames = []
for i in range(40):
    loop.step(); frames.append(cv2.imencode(".png", loop.rig.render_rgb(loop.data, "front")[..., ::-1])[1].tobytes())
loop.close()
N = 300
ts = get_typestore(Stores.ROS2_HUMBLE); T = ts.types
CI = T["sensor_msgs/msg/CompressedImage"]; Odo = T["nav_msgs/msg/Odometry"]
def hdr(i, f): return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](i // 20, (i % 20) * 50_000_000), f)
def odom(i):
    pose = T["geometry_msgs/msg/PoseWithCovariance"](T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](i, 0, 0), T["geometry_msgs/msg/Quaternion"](0, 0, 0, 1)), np.zeros(36))
    tw = T["geometry_msgs/msg/TwistWithCovariance"](T["geometry_msgs/msg/Twist"](T["geometry_msgs/msg/Vector3"](1, 0, 0), T["geometry_msgs/msg/Vector3"](0, 0, 0)), np.zeros(36))
    return Odo(hdr(i, "odom"), "base_link", pose, tw)
d = Path(tempfile.mkdtemp())
res = {}
for name, mode in (("rosbags", CompressionMode.NONE), ("rosbags zstd", CompressionMode.STORAGE)):
    t = time.perf_counter()
    w = Writer(d / name.replace(" ", "_"), version=9, storage_plugin=StoragePlugin.MCAP)
    w.set_compression(mode, CompressionFormat.ZSTD)
    with w:
        ci = w.add_connection("/camera/front/image/compressed", CI.__msgtype__, typestore=ts)
        co = w.add_connection("/odom", Odo.__msgtype__, typestore=ts)
        for i in range(N):
            w.write(ci, i * 50_000_000, ts.serialize_cdr(CI(hdr(i, "front"), "png", np.frombuffer(frames[i % 40], np.uint8)), CI.__msgtype__))
            w.write(co, i * 50_000_000, ts.serialize_cdr(odom(i), Odo.__msgtype__))
    res[name] = (time.perf_counter() - t, sum(f.stat().st_size for f in (d / name.replace(" ", "_")).rglob("*") if f.is_file()))
for name, comp in (("mcap_ros2 none", CompressionType.NONE), ("mcap_ros2 zstd", CompressionType.ZSTD)):
    t = time.perf_counter()
    with open(d / f"{name}.mcap", "wb") as f:
        w = MW(f, compression=comp)
        sci = w.register_msgdef("sensor_msgs/msg/CompressedImage", ts.generate_msgdef("sensor_msgs/msg/CompressedImage", ros_version=2)[0])
        so = w.register_msgdef("nav_msgs/msg/Odometry", ts.generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)[0])
        for i in range(N):
            h = {"stamp": {"sec": i // 20, "nanosec": (i % 20) * 50_000_000}}
            w.write_message("/camera/front/image/compressed", sci, {"header": {**h, "frame_id": "front"}, "format": "png", "data": frames[i % 40]}, log_time=i * 50_000_000)
            w.write_message("/odom", so, {"header": {**h, "frame_id": "odom"}, "child_frame_id": "base_link",
                "pose": {"pose": {"position": {"x": float(i), "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}, "covariance": [0.0] * 36},
                "twist": {"twist": {"linear": {"x": 1.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}, "covariance": [0.0] * 36}}, log_time=i * 50_000_000)
        w.finish()
    res[name] = (time.perf_counter() - t, (d / f"{name}.mcap").stat().st_size)
print(f"{N} steps, PNG frames {np.mean([len(f) for f in frames])/1e3:.0f} kB mean (+ one Odometry per step)")
for k, (t, s) in res.items():
    print(f"  {k:<16} {t * 1e3 / N:6.2f} ms/step  {s / 1e6:7.1f} MB")
shutil.rmtree(d)
