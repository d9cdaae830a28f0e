"""Record a closed-loop run as a ROS 2 bag in MCAP storage (`avsim run --mcap`), with rosbags.

    loop = ClosedLoop(config)
    with BagRecorder(loop, "run.mcap") as bag:
        result = loop.run(on_step=bag.on_step)
        bag.set_result(result)

Topics, one message per control step unless said otherwise, stamped with the step's sensing
time (simulated; `/clock` carries it too). Frames are listed in `avsim.recording.ros_types`.
    /camera/<cam>/image/compressed   sensor_msgs/CompressedImage: the camera's RGB render, PNG
                                     (lossless, the default) or JPEG
    /camera/<cam>/camera_info        sensor_msgs/CameraInfo: K = the intrinsics the pinhole range
                                     estimate uses, no distortion
    /perception/detections           vision_msgs/Detection2DArray: every camera's detections of the
                                     step; each Detection2D's frame is its camera's optical frame, its
                                     hypothesis the class name and score, its box centre and size [px]
    /camera/<cam>/detections/marker  visualization_msgs/ImageMarker: the same boxes as one LINE_LIST
                                     in the camera's pixels (red: stop sign, yellow: other), which
                                     Foxglove's image panel draws over the image
    /odom                            nav_msgs/Odometry: odom -> base_link, pose from the car's free
                                     joint, twist in base_link
    /tf                              tf2_msgs/TFMessage: odom -> base_link (the pose of /odom)
    /tf_static                       tf2_msgs/TFMessage, once: map -> odom (identity), base_link ->
                                     each camera's link -> its optical frame
    /vehicle/command                 ackermann_msgs/AckermannDriveStamped: steering_angle = the steer
                                     command [rad]; speed = the cruise target [m/s] while the policy
                                     drives, 0 once it brakes (avsim's car is commanded by pedals, so
                                     speed is the target the pedals serve, not a set point); the rest 0
    /vehicle/command/raw             std_msgs/Float64MultiArray: [throttle 0-1, brake 0-1, steer_rad],
                                     labelled in its layout, exactly as the policy commanded them
    /clock                           rosgraph_msgs/Clock: the sensing time
    /scene                           visualization_msgs/MarkerArray, once: road edges, stop line, stop
                                     sign and the car's body boxes (`avsim.recording.ros_scene`)
    /avsim/run                       std_msgs/String, once at the end: JSON {"config", "result"}
The cameras are "front", and "side" where the policy uses it. Pixel coordinates are avsim's:
pixel i covers [i, i + 1), so the centre of pixel (0, 0) is (0.5, 0.5) (OpenCV's convention
puts it at (0, 0): subtract 0.5 from every box coordinate and from K's cx, cy to convert).

Which state a message shows: as in `RunRecorder`, a record holds its step's sensing-time state,
and `on_step` runs after that step's physics, when the state is the next step's sensing state;
the recorder captures the images and the pose then, and writes them with the next record. The
odometry pose is read from the free joint (qpos), as the record's `x_m`, `y_m`, `yaw_rad` are.

The bag is written by rosbags into a hidden folder beside `path`; on `close()` its `.mcap`
file is moved to `path` (the folder's metadata.yaml, which only `ros2 bag` directories need,
is dropped: Foxglove, rosbags and `ros2 bag play` read a bare `.mcap`). An interrupted run
leaves no file at `path`.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import mujoco
import numpy as np

from avsim.control.policies import STOP_CLASS
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.metrics import RunResult, StepRecord
from avsim.perception.base import Detection
from avsim.recording import ros_types
from avsim.recording.ros_scene import scene_markers
from avsim.recording.ros_types import BASE_FRAME, MAP_FRAME, ODOM_FRAME, camera_link, header, optical_frame, time_ns
from avsim.recording.step_recorder import StepRecorder
from avsim.world.scene import CAR_PREFIX

IMAGE_FORMATS = ("png", "jpeg")
DEFAULT_JPEG_QUALITY = 90
RUN_TOPIC = "/avsim/run"
DETECTIONS_TOPIC = "/perception/detections"
RAW_COMMAND_LABELS = ("throttle", "brake", "steer_rad")
# Box colours (r, g, b, a in 0-1), as in the rerun recording and the video.
_STOP_RGBA = (1.0, 0.16, 0.16, 1.0)
_OTHER_RGBA = (1.0, 0.78, 0.0, 1.0)


def image_topic(camera: str) -> str:
    """Topic of a camera's sensor_msgs/CompressedImage ("/camera/front/image/compressed")."""
    return f"/camera/{camera}/image/compressed"


def camera_info_topic(camera: str) -> str:
    """Topic of a camera's sensor_msgs/CameraInfo."""
    return f"/camera/{camera}/camera_info"


def marker_topic(camera: str) -> str:
    """Topic of a camera's detection boxes as one visualization_msgs/ImageMarker (a LINE_LIST)."""
    return f"/camera/{camera}/detections/marker"


@dataclass(frozen=True)
class _Frame:
    """What the recorder captured of one sensing state (world frame, SI units)."""

    time_s: float
    images: dict[str, bytes]  # camera -> encoded image
    position_m: np.ndarray  # (3,) body origin, from qpos
    quat_wxyz: np.ndarray  # (4,) body orientation, from qpos
    velocity_body_mps: np.ndarray  # (3,) linear velocity in base_link
    angular_body_radps: np.ndarray  # (3,) angular velocity in base_link


class BagRecorder(StepRecorder):
    """Writes one `ClosedLoop` run to `path` (a `.mcap` ROS 2 bag); attach before the first step.

    image_format: "png" (lossless, default) or "jpeg" (`jpeg_quality`, 0-100).
    """

    def __init__(self, loop: ClosedLoop, path: str | os.PathLike, *, image_format: str = "png",
                 jpeg_quality: int = DEFAULT_JPEG_QUALITY) -> None:
        self._check_unstarted(loop)
        if image_format not in IMAGE_FORMATS:
            raise ConfigError(f"image format must be one of {', '.join(IMAGE_FORMATS)}, got '{image_format}'")
        self._path = Path(path)
        if self._path.suffix != ".mcap":
            raise ConfigError(f"--mcap expects a path ending in .mcap, got '{self._path}'")
        ros_types.require_rosbags()
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

        self._store = ros_types.typestore()
        self._types = self._store.types
        self._attach(loop)
        self._format = image_format
        self._encode_params = [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality] if image_format == "jpeg" else []
        self.cameras = self.recorded_cameras(loop)
        free = loop.model.joint(CAR_PREFIX + "car_free")
        self._qpos, self._qvel = int(free.qposadr[0]), int(free.dofadr[0])
        self._cruise_mps = loop.config.scenario.speed_kmh / 3.6
        self._result: RunResult | None = None
        self._braked = False
        self._path.parent.mkdir(parents=True, exist_ok=True)
        # rosbags writes a bag folder, <folder>/<folder name>.mcap; it is made inside a hidden folder
        # beside `path` (one file system, so the move is atomic) and named after `path`, so the
        # file's rosbag2 metadata record names the final file and the same run gives the same bytes.
        self._tmp_dir = self._path.with_name(f".{self._path.name}.{os.getpid()}.{secrets.token_hex(6)}.bag")
        self._bag_dir = self._tmp_dir / self._path.stem
        self._writer = Writer(self._bag_dir, version=9, storage_plugin=StoragePlugin.MCAP)
        # PNG and JPEG data are compressed already; zstd chunks still save about a fifth
        # (docs/ros.md) for well under a millisecond a step.
        self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        try:
            self._writer.open()
            self._connections = self._open_topics()
            self._write_static()
            self._pending = self._capture()
        except BaseException:
            self.abort()
            raise

    # ---- per step --------------------------------------------------------------------
    def _step(self, frame: _Frame, record: StepRecord) -> None:
        """Write `record` with the frame captured at its sensing time; called by `StepRecorder.on_step`."""
        self._write_step(frame, record)

    def set_result(self, result: RunResult) -> None:
        """The run's result, written to /avsim/run with the config when the bag is closed."""
        self._result = result

    def _finish(self) -> None:
        """Write /avsim/run, finish the bag and move its .mcap to `path`; called by `StepRecorder.close`."""
        payload = {"config": self._loop.config.to_dict(),
                   "result": self._result.to_json_dict() if self._result is not None else None}
        last_ns = time_ns(self._pending.time_s)
        self._write(RUN_TOPIC, last_ns, self._types["std_msgs/msg/String"](data=json.dumps(payload, sort_keys=True)))
        self._writer.close()
        os.replace(self._bag_dir / f"{self._bag_dir.name}.mcap", self._path)
        shutil.rmtree(self._tmp_dir)

    def _discard(self) -> None:
        """Stop recording and delete the partial bag; `path` is left untouched."""
        shutil.rmtree(self._tmp_dir, ignore_errors=True)


    # ---- capture ---------------------------------------------------------------------
    def _capture(self) -> _Frame:
        loop = self._loop
        q, v = loop.data.qpos, loop.data.qvel
        quat = q[self._qpos + 3: self._qpos + 7].copy()
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, quat)
        # A free joint's linear velocity is in the world frame and its angular velocity in the body's.
        velocity_body = rotation.reshape(3, 3).T @ v[self._qvel: self._qvel + 3]
        images = {}
        for cam in self.cameras:
            bgr = np.ascontiguousarray(loop.rig.render_rgb(loop.data, cam)[..., ::-1])
            ok, buffer = cv2.imencode(".png" if self._format == "png" else ".jpg", bgr, self._encode_params)
            if not ok:
                raise RuntimeError(f"{self._format} encoding of a camera frame failed")
            images[cam] = buffer.tobytes()
        return _Frame(loop.time_s, images, q[self._qpos: self._qpos + 3].copy(), quat, velocity_body,
                      v[self._qvel + 3: self._qvel + 6].copy())

    # ---- writing ---------------------------------------------------------------------
    def _open_topics(self) -> dict[str, Any]:
        topics = {"/tf": "tf2_msgs/msg/TFMessage", "/tf_static": "tf2_msgs/msg/TFMessage", "/odom": "nav_msgs/msg/Odometry",
                  DETECTIONS_TOPIC: "vision_msgs/msg/Detection2DArray",
                  "/vehicle/command": "ackermann_msgs/msg/AckermannDriveStamped",
                  "/vehicle/command/raw": "std_msgs/msg/Float64MultiArray", "/clock": "rosgraph_msgs/msg/Clock",
                  RUN_TOPIC: "std_msgs/msg/String", "/scene": "visualization_msgs/msg/MarkerArray"}
        for cam in self.cameras:
            topics[image_topic(cam)] = "sensor_msgs/msg/CompressedImage"
            topics[camera_info_topic(cam)] = "sensor_msgs/msg/CameraInfo"
            topics[marker_topic(cam)] = "visualization_msgs/msg/ImageMarker"
        connections = {}
        for topic, msgtype in topics.items():
            connections[topic] = self._writer.add_connection(topic, msgtype, typestore=self._store)
        return connections

    def _write(self, topic: str, stamp_ns: int, message: Any) -> None:
        connection = self._connections[topic]
        self._writer.write(connection, stamp_ns, self._store.serialize_cdr(message, connection.msgtype))

    def _write_static(self) -> None:
        model = self._loop.model
        car_body = model.body(CAR_PREFIX + "car").id
        transforms = [self._transform(0.0, MAP_FRAME, ODOM_FRAME, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))]
        for cam in self.cameras:
            cam_id = model.camera(CAR_PREFIX + cam).id
            if model.cam_bodyid[cam_id] != car_body:
                raise RuntimeError(f"the {cam} camera is not fixed to the car body; its transform would not be static")
            mj_axes = np.zeros(9)
            mujoco.mju_quat2Mat(mj_axes, model.cam_quat[cam_id])
            right, up, back = mj_axes.reshape(3, 3).T  # MuJoCo camera axes in the body frame
            link_axes = np.column_stack([-back, -right, up])  # x forward, y left, z up
            optical_axes = np.column_stack([right, -up, -back])  # x right, y down, z forward
            transforms.append(self._transform(0.0, BASE_FRAME, camera_link(cam), model.cam_pos[cam_id], _quat_wxyz(link_axes)))
            transforms.append(self._transform(0.0, camera_link(cam), optical_frame(cam), np.zeros(3),
                                              _quat_wxyz(link_axes.T @ optical_axes)))
        self._write("/tf_static", 0, self._types["tf2_msgs/msg/TFMessage"](transforms=transforms))
        self._write("/scene", 0, scene_markers(self._types, model, self._loop.scene))

    def _transform(self, time_s: float, parent: str, child: str, translation_m: np.ndarray, quat_wxyz: np.ndarray) -> Any:
        t = self._types
        w, x, y, z = (float(c) for c in quat_wxyz)
        return t["geometry_msgs/msg/TransformStamped"](
            header=header(time_s, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](translation=t["geometry_msgs/msg/Vector3"](*map(float, translation_m)),
                                                       rotation=t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)))

    def _write_step(self, frame: _Frame, record: StepRecord) -> None:
        t = self._types
        time_s, stamp_ns = record.time_s, time_ns(record.time_s)
        self._write("/clock", stamp_ns, t["rosgraph_msgs/msg/Clock"](clock=ros_types.stamp(time_s)))
        for cam in self.cameras:
            self._write(image_topic(cam), stamp_ns, t["sensor_msgs/msg/CompressedImage"](
                header=header(time_s, optical_frame(cam)), format=self._format,
                data=np.frombuffer(frame.images[cam], dtype=np.uint8)))
            self._write(camera_info_topic(cam), stamp_ns, self._camera_info(time_s, cam))
            self._write(marker_topic(cam), stamp_ns, self._marker(time_s, cam, record.detections))
        self._write(DETECTIONS_TOPIC, stamp_ns, t["vision_msgs/msg/Detection2DArray"](
            header=header(time_s, BASE_FRAME), detections=[self._detection(time_s, d) for d in record.detections]))
        odom_tf = self._transform(time_s, ODOM_FRAME, BASE_FRAME, frame.position_m, frame.quat_wxyz)
        self._write("/tf", stamp_ns, t["tf2_msgs/msg/TFMessage"](transforms=[odom_tf]))
        self._write("/odom", stamp_ns, self._odometry(time_s, frame))
        # The loop latches braking at the first brake command (and then never throttles again).
        self._braked = self._braked or record.brake > 0
        self._write("/vehicle/command", stamp_ns, t["ackermann_msgs/msg/AckermannDriveStamped"](
            header=header(time_s, BASE_FRAME), drive=t["ackermann_msgs/msg/AckermannDrive"](
                steering_angle=record.steer_rad, steering_angle_velocity=0.0,
                speed=0.0 if self._braked else self._cruise_mps, acceleration=0.0, jerk=0.0)))
        layout = t["std_msgs/msg/MultiArrayLayout"](dim=[t["std_msgs/msg/MultiArrayDimension"](
            label=",".join(RAW_COMMAND_LABELS), size=len(RAW_COMMAND_LABELS), stride=len(RAW_COMMAND_LABELS))], data_offset=0)
        self._write("/vehicle/command/raw", stamp_ns, t["std_msgs/msg/Float64MultiArray"](
            layout=layout, data=np.array([record.throttle, record.brake, record.steer_rad], dtype=np.float64)))

    def _camera_info(self, time_s: float, camera: str) -> Any:
        intrinsics = self._loop.rig.intrinsics(camera)
        k = intrinsics.matrix()
        projection = np.hstack([k, np.zeros((3, 1))])
        return self._types["sensor_msgs/msg/CameraInfo"](
            header=header(time_s, optical_frame(camera)), height=intrinsics.height_px, width=intrinsics.width_px,
            distortion_model="plumb_bob", d=np.zeros(5), k=k.reshape(9), r=np.eye(3).reshape(9), p=projection.reshape(12),
            binning_x=0, binning_y=0,
            roi=self._types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))

    def _detection(self, time_s: float, detection: Detection) -> Any:
        t = self._types
        x0, y0, x1, y1 = detection.box_xyxy_px
        pose = t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](0.0, 0.0, 0.0),
                                             orientation=t["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)),
            covariance=np.zeros(36))
        hypothesis = t["vision_msgs/msg/ObjectHypothesisWithPose"](
            hypothesis=t["vision_msgs/msg/ObjectHypothesis"](class_id=detection.class_name, score=detection.confidence), pose=pose)
        box = t["vision_msgs/msg/BoundingBox2D"](
            center=t["vision_msgs/msg/Pose2D"](position=t["vision_msgs/msg/Point2D"](x=(x0 + x1) / 2, y=(y0 + y1) / 2), theta=0.0),
            size_x=x1 - x0, size_y=y1 - y0)
        return t["vision_msgs/msg/Detection2D"](header=header(time_s, optical_frame(detection.camera)), results=[hypothesis],
                                                bbox=box, id=detection.source)

    def _marker(self, time_s: float, camera: str, detections: tuple[Detection, ...]) -> Any:
        """The camera's boxes as one LINE_LIST: four edges, eight points, per box."""
        t = self._types
        points, colours = [], []
        for d in detections:
            if d.camera != camera:
                continue
            x0, y0, x1, y1 = d.box_xyxy_px
            corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
            colour = t["std_msgs/msg/ColorRGBA"](*(_STOP_RGBA if d.class_name == STOP_CLASS else _OTHER_RGBA))
            for i in range(4):
                for x, y in (corners[i], corners[(i + 1) % 4]):
                    points.append(t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0))
                    colours.append(colour)
        return t["visualization_msgs/msg/ImageMarker"](
            header=header(time_s, optical_frame(camera)), ns="detections", id=0, type=2, action=0,  # LINE_LIST, ADD
            position=t["geometry_msgs/msg/Point"](0.0, 0.0, 0.0), scale=2.0,
            outline_color=t["std_msgs/msg/ColorRGBA"](*_STOP_RGBA), filled=0, fill_color=t["std_msgs/msg/ColorRGBA"](0.0, 0.0, 0.0, 0.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), points=points, outline_colors=colours)

    def _odometry(self, time_s: float, frame: _Frame) -> Any:
        t = self._types
        w, x, y, z = (float(c) for c in frame.quat_wxyz)
        pose = t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](*map(float, frame.position_m)),
                                             orientation=t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)),
            covariance=np.zeros(36))
        twist = t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](linear=t["geometry_msgs/msg/Vector3"](*map(float, frame.velocity_body_mps)),
                                               angular=t["geometry_msgs/msg/Vector3"](*map(float, frame.angular_body_radps))),
            covariance=np.zeros(36))
        return t["nav_msgs/msg/Odometry"](header=header(time_s, ODOM_FRAME), child_frame_id=BASE_FRAME, pose=pose, twist=twist)


def _quat_wxyz(rotation: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).reshape(9))
    return quat
