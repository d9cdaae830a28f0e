"""Record a closed-loop run to a rerun `.rrd` file.

    loop = ClosedLoop(config)
    with RunRecorder(loop, "run.rrd") as recorder:
        loop.run(on_step=recorder.on_step)

Per control step (timelines `frame` = step index and `sim_time` = sensing time [s]):
camera images (JPEG) with their pinhole intrinsics and world pose, the detections
as boxes on the images, the car pose and trajectory, and the `StepRecord` scalars
under `metrics/<field>`. The stop sign, stop line and road are static. Entity paths
are listed in `avsim.recording.paths`; the default layout is `blueprint.default_blueprint`.

When the images are taken: a `StepRecord` holds the state at sensing time, the start
of its step, but `on_step` is called after that step's physics. The state then is
the sensing-time state of the *next* step (nothing moves between `on_step` and the
next step's sensing), so the recorder renders the cameras in `on_step`, keeps the
frame, and logs it with the next record; the first frame is rendered when the
recorder is attached. Every image therefore shows exactly the state whose
detections, commands and metrics it is logged with. The state the run ends in is
logged as one last frame (images and car pose, no detections or metrics).

Images, camera poses and the car pose come from MuJoCo's derived kinematics (xpos,
cam_xpos), as the perception's renders do. After `mj_step` these lag qpos by one
physics step (`loop.physics_dt_s`, about 2 cm at 85 km/h), so the logged car pose
is that much behind the record's `x_m`, which is read from qpos. The recorder does
not call `mj_forward` to refresh them: that would change what the next step's
perception sees, and a recorded run must be the run that would have happened.

The file is written to a temporary name beside `path` and renamed on `close()`, so
an interrupted run leaves no half-written `.rrd`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np
import rerun as rr

from avsim.control.policies import STOP_CLASS
from avsim.errors import ConfigError, OutputError
from avsim.loop import ClosedLoop
from avsim.metrics import StepRecord
from avsim.outputs import temporary_path
from avsim.perception.base import Detection
from avsim.recording import paths
from avsim.recording.blueprint import default_blueprint
from avsim.recording.static_scene import log_pinhole, log_world
from avsim.sensors.camera import CameraPose
from avsim.world.scene import CAR_PREFIX

APPLICATION_ID = "avsim"
DEFAULT_JPEG_QUALITY = 85
# The trajectory is drawn on the road, not at the body origin (wheel-centre height) [m].
TRAJECTORY_Z_M = 0.05
# Sensing times of a frame and its record agree to well under one physics step [s].
_TIME_TOLERANCE_S = 1e-6

# Series name and colour per metric field, shown in the time-series legends.
SERIES_STYLE: dict[str, tuple[str, tuple[int, int, int]]] = {
    "speed_mps": ("speed [m/s]", (40, 120, 220)),
    "throttle": ("throttle", (40, 170, 70)),
    "brake": ("brake", (220, 40, 40)),
    "stop_line_dist_m": ("true [m]", (200, 200, 200)),
    "est_stop_line_dist_m": ("estimated [m]", (240, 150, 30)),
    "top_stop_conf": ("confidence", (150, 80, 200)),
    "required_decel_mps2": ("required deceleration [m/s^2]", (220, 90, 90)),
    "pitch_rad": ("body pitch, nose down [rad]", (90, 90, 90)),
    "max_brake_slip": ("largest wheel slip while braking", (200, 120, 40)),
}
_STOP_BOX_COLOUR = (255, 40, 40)
_OTHER_BOX_COLOUR = (255, 200, 0)
_TRAJECTORY_COLOUR = (40, 120, 220)


@dataclass(frozen=True)
class _Frame:
    """What the recorder captured of one simulation state (world frame, SI units)."""

    time_s: float  # loop.time_s of the state
    car_position_m: np.ndarray  # (3,) car body origin
    car_quat_wxyz: np.ndarray  # (4,) car body orientation
    images_jpeg: dict[str, bytes]  # camera name -> JPEG of its RGB render
    camera_poses: dict[str, CameraPose]


class RunRecorder:
    """Logs one `ClosedLoop` run to `path` (an `.rrd` file); attach before the first step.

    cameras: "front" always, and "side" when the policy uses it.
    jpeg_quality: 0-100; at 85 a 640x480 frame is about 25 kB (a full 85 km/h run is about 8 MB).
    """

    def __init__(self, loop: ClosedLoop, path: str | os.PathLike, *, jpeg_quality: int = DEFAULT_JPEG_QUALITY) -> None:
        if loop.records:
            raise ValueError("attach the RunRecorder before the loop's first step")
        if not 0 <= jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be in [0, 100], got {jpeg_quality}")
        self._loop = loop
        self._path = Path(path)
        self._jpeg_quality = jpeg_quality
        self.cameras: tuple[str, ...] = ("front", *(c for c in loop.policy.cameras if c != "front"))
        self._car_body = loop.model.body(CAR_PREFIX + "car").id
        self._trajectory_m: list[tuple[float, float, float]] = []
        self._steps = 0
        self._closed = False

        self._rec = rr.RecordingStream(APPLICATION_ID)
        self._path.parent.mkdir(parents=True, exist_ok=True)
        # A unique hidden name beside `path` (same file system, so the rename is atomic), which
        # a later write of `path` removes if this process is killed; rerun creates the file,
        # with the user's usual permissions.
        self._tmp_path = temporary_path(self._path)
        try:
            if not self._rec.is_enabled():
                raise ConfigError("rerun logging is disabled (RERUN=off in the environment); unset RERUN to write --rrd")
            # The run's clocks are sim_time and frame; wall-clock log_time would be a misleading third.
            self._rec.set_log_time_enabled(False)
            self._rec.save(self._tmp_path, default_blueprint=default_blueprint(self.cameras))
            self._log_static()
            self._pending = self._capture()  # the sensing-time state of step 0
        except BaseException:
            self.abort()
            raise

    # ---- per step --------------------------------------------------------------------
    def on_step(self, loop: ClosedLoop, record: StepRecord) -> None:
        """Log `record` with the frame captured at its sensing time; `loop.run(on_step=...)` hook."""
        if self._closed:
            raise RuntimeError("on_step called on a closed RunRecorder")
        if loop is not self._loop:
            raise ValueError("on_step called with a different ClosedLoop than the recorder was built for")
        frame = self._pending
        if abs(frame.time_s - record.time_s) > _TIME_TOLERANCE_S:
            raise RuntimeError(f"frame at t = {frame.time_s:.3f} s but record at t = {record.time_s:.3f} s: "
                               "on_step must be called once after every loop step")
        self._set_time(self._steps, record.time_s)
        self._log_frame(frame)
        self._log_detections(record.detections)
        self._log_metrics(record)
        self._steps += 1
        # The state now is the next step's sensing state (see the module docstring).
        self._pending = self._capture()

    def close(self) -> None:
        """Log the final state, flush, finish the file and move it to `path`. Idempotent."""
        if self._closed:
            return
        try:
            self._set_time(self._steps, self._pending.time_s)
            self._log_frame(self._pending)
            self._log_detections(())  # no perception ran on the final state
            try:
                self._rec.flush()
                self._rec.disconnect()  # writes the footer and closes the file
                os.replace(self._tmp_path, self._path)
            except Exception as exc:
                # rerun's file writer runs in a thread and reports a full disk (or a file-size
                # limit) only as "shut down prematurely" at the flush: said here in the user's terms.
                raise OutputError(f"cannot write {self._path}: the recording could not be finished "
                                  f"({_one_line(exc)}); is the disk full?") from None
        except BaseException:
            self.abort()
            raise
        self._closed = True

    def abort(self) -> None:
        """Stop recording and delete the partial file; `path` is left untouched."""
        self._closed = True
        if self._rec.is_enabled():  # a disabled stream has nothing to close (and warns if asked)
            self._rec.disconnect()
        self._tmp_path.unlink(missing_ok=True)

    def __enter__(self) -> RunRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # ---- capture ---------------------------------------------------------------------
    def _capture(self) -> _Frame:
        loop = self._loop
        images, poses = {}, {}
        for cam in self.cameras:
            images[cam] = self._encode_jpeg(loop.rig.render_rgb(loop.data, cam))
            poses[cam] = loop.rig.pose(loop.data, cam)
        return _Frame(
            time_s=loop.time_s,
            car_position_m=loop.data.xpos[self._car_body].copy(),
            car_quat_wxyz=loop.data.xquat[self._car_body].copy(),
            images_jpeg=images,
            camera_poses=poses,
        )

    def _encode_jpeg(self, rgb: np.ndarray) -> bytes:
        ok, buffer = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, self._jpeg_quality])
        if not ok:
            raise RuntimeError("JPEG encoding of a camera frame failed")
        return buffer.tobytes()

    # ---- logging ---------------------------------------------------------------------
    def _log(self, entity: str, archetype: rr.AsComponents) -> None:
        self._rec.log(entity, archetype, strict=True)

    def _set_time(self, frame_index: int, time_s: float) -> None:
        self._rec.set_time(paths.FRAME_TIMELINE, sequence=frame_index)
        self._rec.set_time(paths.SIM_TIME_TIMELINE, duration=time_s)

    def _log_static(self) -> None:
        loop = self._loop
        scenario, policy = loop.config.scenario, loop.config.policy
        self._rec.send_recording_name(
            f"{scenario.town} {scenario.placement} {policy.name} {loop.config.perception.kind} "
            f"{scenario.sign} {scenario.speed_kmh:g} km/h seed {scenario.seed}")
        log_world(self._rec, loop.model, loop.scene)
        for cam in self.cameras:
            log_pinhole(self._rec, cam, loop.rig.intrinsics(cam))
        # Styles that never change are static, so each step logs only the data.
        self._rec.log(paths.TRAJECTORY, rr.LineStrips3D.from_fields(colors=[_TRAJECTORY_COLOUR], radii=[0.1]), static=True, strict=True)
        for field in paths.METRIC_FIELDS:
            name, colour = SERIES_STYLE[field]
            self._rec.log(paths.metric(field), rr.SeriesLines(names=name, colors=[colour]), static=True, strict=True)

    def _log_frame(self, frame: _Frame) -> None:
        w, x, y, z = frame.car_quat_wxyz
        self._log(paths.CAR, rr.Transform3D(translation=frame.car_position_m, quaternion=rr.Quaternion(xyzw=[x, y, z, w])))
        self._trajectory_m.append((float(frame.car_position_m[0]), float(frame.car_position_m[1]), TRAJECTORY_Z_M))
        self._log(paths.TRAJECTORY, rr.LineStrips3D([self._trajectory_m]))
        for cam in self.cameras:
            pose = frame.camera_poses[cam]
            # The pose's rotation columns are the camera axes in the world: camera -> world.
            self._log(paths.camera(cam), rr.Transform3D(translation=pose.position_m, mat3x3=pose.rotation))
            self._log(paths.camera_image(cam), rr.EncodedImage(contents=frame.images_jpeg[cam], media_type="image/jpeg"))

    def _log_detections(self, detections: tuple[Detection, ...]) -> None:
        for cam in self.cameras:
            dets = [d for d in detections if d.camera == cam]
            # An empty batch is logged too, so the previous step's boxes do not linger.
            self._log(paths.camera_detections(cam), rr.Boxes2D(
                array=np.array([d.box_xyxy_px for d in dets], dtype=float).reshape(-1, 4),
                array_format=rr.Box2DFormat.XYXY,
                labels=[f"{d.class_name} {d.confidence:.2f}" for d in dets],
                colors=[_STOP_BOX_COLOUR if d.class_name == STOP_CLASS else _OTHER_BOX_COLOUR for d in dets],
                show_labels=True,
            ))

    def _log_metrics(self, record: StepRecord) -> None:
        for field in paths.METRIC_FIELDS:
            value = getattr(record, field)
            if value is not None and math.isfinite(value):
                self._log(paths.metric(field), rr.Scalars(float(value)))


def _one_line(exc: BaseException) -> str:
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__
