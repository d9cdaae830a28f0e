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

The per-step data is kept in memory (JPEG images, a few kB each) and sent on `close()`
as one column per entity and component (`RecordingStream.send_columns`): a run's file holds
a few dozen chunks instead of one per logged value, and logging costs a few calls instead of
a dozen per step.

rerun logs into a memory sink (`RecordingStream.memory_recording`), and `close()` writes its
bytes with avsim's own checked write: into a temporary file beside `path` (created when the
recorder starts, so an unwritable place fails before the run), fsynced, then renamed,
so an interrupted run leaves no half-written `.rrd`. rerun's own file sink is not used: its
writer thread reports a full disk only as "shut down prematurely", and a process whose writer
died that way waited for it for ever at exit. Written from Python, a full disk is an OSError,
reported in one line naming the file.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import rerun as rr

from avsim.control.policies import STOP_CLASS
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.metrics import StepRecord
from avsim.outputs import reserve_temporary, write_reserved
from avsim.recording import paths
from avsim.recording.blueprint import default_blueprint
from avsim.recording.static_scene import log_pinhole, log_world
from avsim.recording.step_recorder import StepRecorder
from avsim.sensors.camera import CameraPose
from avsim.world.scene import CAR_PREFIX

APPLICATION_ID = "avsim"
DEFAULT_JPEG_QUALITY = 85
# The trajectory is drawn on the road, not at the body origin (wheel-centre height) [m].
TRAJECTORY_Z_M = 0.05

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


class RunRecorder(StepRecorder):
    """Logs one `ClosedLoop` run to `path` (an `.rrd` file); attach before the first step.

    cameras: "front" always, and "side" when the policy uses it.
    jpeg_quality: 0-100; at 85 a 640x480 frame is about 25 kB (a full 85 km/h run is about 8 MB).
    """

    def __init__(self, loop: ClosedLoop, path: str | os.PathLike, *, jpeg_quality: int = DEFAULT_JPEG_QUALITY) -> None:
        self._check_unstarted(loop)
        if not 0 <= jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality must be in [0, 100], got {jpeg_quality}")
        self._attach(loop)
        self._path = Path(path)
        self._jpeg_quality = jpeg_quality
        self.cameras = self.recorded_cameras(loop)
        self._car_body = loop.model.body(CAR_PREFIX + "car").id
        self._frames: list[_Frame] = []  # one per step, captured at its sensing time
        self._records: list[StepRecord] = []

        self._rec = rr.RecordingStream(APPLICATION_ID)
        # The file's temporary name is taken now, so an unwritable place fails before the run;
        # it is filled and renamed to `path` at close.
        self._tmp_path = reserve_temporary(self._path)
        try:
            if not self._rec.is_enabled():
                raise ConfigError("rerun logging is disabled (RERUN=off in the environment); unset RERUN to write --rrd")
            # The run's clocks are sim_time and frame; wall-clock log_time would be a misleading third.
            self._rec.set_log_time_enabled(False)
            self._memory = self._rec.memory_recording()  # see the module docstring
            rr.send_blueprint(default_blueprint(self.cameras), make_active=False, make_default=True, recording=self._rec)
            self._log_static()
            self._pending = self._capture()  # the sensing-time state of step 0
        except BaseException:
            self.abort()
            raise

    # ---- per step --------------------------------------------------------------------
    def _step(self, frame: _Frame, record: StepRecord) -> None:
        """Keep `record` with the frame captured at its sensing time; called by `StepRecorder.on_step`."""
        self._frames.append(frame)
        self._records.append(record)

    def _finish(self) -> None:
        """Send the steps and the final state, and write the file to `path` through its temporary
        name (a full disk is an OutputError naming `path`); called by `StepRecorder.close`."""
        self._send_columns([*self._frames, self._pending], self._records)
        data = self._memory.drain_as_bytes()  # flushes rerun's batcher first
        self._rec.disconnect()
        write_reserved(self._tmp_path, self._path, data)

    def _discard(self) -> None:
        """Stop recording and delete the temporary file; `path` is left untouched."""
        if self._rec.is_enabled():  # a disabled stream has nothing to close (and warns if asked)
            self._rec.disconnect()
        self._tmp_path.unlink(missing_ok=True)

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
    def _log_static(self) -> None:
        loop = self._loop
        scenario, policy = loop.config.scenario, loop.config.policy
        self._rec.send_recording_name(
            f"{scenario.town} {scenario.placement} {policy.name} {loop.config.perception.kind} "
            f"{scenario.sign} {scenario.speed_kmh:g} km/h seed {scenario.seed}")
        log_world(self._rec, loop.model, loop.scene)
        for cam in self.cameras:
            log_pinhole(self._rec, cam, loop.rig.intrinsics(cam))
        # Styles that never change are static, so the columns hold only the data.
        self._rec.log(paths.TRAJECTORY, rr.LineStrips3D.from_fields(colors=[_TRAJECTORY_COLOUR], radii=[0.1]), static=True, strict=True)
        for field in paths.METRIC_FIELDS:
            name, colour = SERIES_STYLE[field]
            self._rec.log(paths.metric(field), rr.SeriesLines(names=name, colors=[colour]), static=True, strict=True)

    def _send(self, entity: str, rows: list[int], times_s: list[float], columns: Iterable[Any]) -> None:
        """One column per component of `entity`, a row per step in `rows` (frame indices)."""
        self._rec.send_columns(entity, indexes=[
            rr.TimeColumn(paths.FRAME_TIMELINE, sequence=rows),
            rr.TimeColumn(paths.SIM_TIME_TIMELINE, duration=[times_s[i] for i in rows]),
        ], columns=columns, strict=True)

    def _send_columns(self, frames: list[_Frame], records: list[StepRecord]) -> None:
        """Every step's frame (and the final state's, one more than `records`), detections and metrics."""
        every = list(range(len(frames)))
        # A record's sensing time, and the final state's time for the last frame.
        times_s = [r.time_s for r in records] + [frames[-1].time_s]
        self._send(paths.CAR, every, times_s, rr.Transform3D.columns(
            translation=np.array([f.car_position_m for f in frames]),
            quaternion=np.array([f.car_quat_wxyz[[1, 2, 3, 0]] for f in frames])))  # rerun's order is xyzw
        trail = [(float(f.car_position_m[0]), float(f.car_position_m[1]), TRAJECTORY_Z_M) for f in frames]
        # One strip per step: the positions so far, so the trail grows as the run plays.
        self._send(paths.TRAJECTORY, every, times_s,
                   rr.LineStrips3D.columns(strips=[trail[:i + 1] for i in every]).partition([1] * len(every)))
        for cam in self.cameras:
            poses = [f.camera_poses[cam] for f in frames]
            # The pose's rotation columns are the camera axes in the world: camera -> world.
            self._send(paths.camera(cam), every, times_s, rr.Transform3D.columns(
                translation=np.array([p.position_m for p in poses]), mat3x3=np.array([p.rotation for p in poses])))
            self._send(paths.camera_image(cam), every, times_s, rr.EncodedImage.columns(
                blob=[f.images_jpeg[cam] for f in frames], media_type=["image/jpeg"] * len(frames)))
            # Every step has a batch, empty ones too, so the previous step's boxes do not linger;
            # the final state has an empty one (no perception ran on it).
            per_step = [[d for d in r.detections if d.camera == cam] for r in records] + [[]]
            boxes = [d for dets in per_step for d in dets]
            xyxy = np.array([d.box_xyxy_px for d in boxes], dtype=float).reshape(-1, 4)
            self._send(paths.camera_detections(cam), every, times_s, rr.Boxes2D.columns(
                centers=(xyxy[:, :2] + xyxy[:, 2:]) / 2, half_sizes=(xyxy[:, 2:] - xyxy[:, :2]) / 2,
                labels=[f"{d.class_name} {d.confidence:.2f}" for d in boxes],
                colors=[_STOP_BOX_COLOUR if d.class_name == STOP_CLASS else _OTHER_BOX_COLOUR for d in boxes],
                show_labels=[True] * len(boxes),
            ).partition([len(dets) for dets in per_step]))
        for field in paths.METRIC_FIELDS:
            values = [getattr(r, field) for r in records]
            rows = [i for i, v in enumerate(values) if v is not None and math.isfinite(v)]
            if rows:
                self._send(paths.metric(field), rows, times_s, rr.Scalars.columns(scalars=[float(values[i]) for i in rows]))

