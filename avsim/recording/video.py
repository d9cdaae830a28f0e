"""Record the front camera of a closed-loop run to an MP4 video (`avsim run --mp4`).

    loop = ClosedLoop(config)
    with VideoRecorder(loop, "run.mp4") as video:
        loop.run(on_step=video.on_step)

Each frame is the front camera's RGB render with the front camera's detections drawn
on it: boxes labelled "class confidence", stop signs red and other classes yellow,
drawn thin when below the policy's `conf_threshold` (reported, but not acted on). A
panel in the top-left corner shows the sim time [s], speed [km/h] and the brake
command [0-1] as a number and a bar. Side-camera detections are not drawn.

Which state a frame shows, as in `RunRecorder`: a `StepRecord` holds the state at
sensing time, the start of its step, but `on_step` is called after that step's
physics, when the state is the *next* step's sensing state. The recorder therefore
renders the front camera in `on_step`, keeps the frame, and writes it with the next
record (the first frame is rendered when the recorder is attached). Every frame shows
exactly the image whose detections are drawn on it, with that step's speed and the
brake command those detections produced. After N steps the video has N + 1 frames:
the last is the state the run ended in, with no detections (no perception ran on it)
and the last brake command, held as the loop holds it.

The frame rate is 1 / `loop.control_dt_s` (20 fps at the defaults), so the video plays
in real (simulated) time. It is encoded with OpenCV's `mp4v` codec into a temporary
file beside `path` and renamed on `close()`, so an interrupted run leaves no file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from avsim.control.policies import STOP_CLASS
from avsim.errors import AvsimError, ConfigError, OutputError
from avsim.image_files import c_stderr_silenced
from avsim.metrics import StepRecord
from avsim.outputs import temporary_path
from avsim.perception.base import Detection
from avsim.recording.step_recorder import StepRecorder

if TYPE_CHECKING:
    from avsim.loop import ClosedLoop

CAMERA = "front"
FOURCC = "mp4v"
# Colours are BGR, OpenCV's channel order; they match the rerun recording's boxes.
_STOP_BOX_BGR = (40, 40, 255)
_OTHER_BOX_BGR = (0, 200, 255)
_TEXT_BGR = (255, 255, 255)
_BRAKE_BAR_BGR = (40, 40, 220)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_FONT_SCALE = 0.5
_PANEL_SIZE_PX = (190, 70)  # width, height of the speed/brake panel
_PANEL_OPACITY = 0.6


@dataclass(frozen=True)
class _Frame:
    """The front camera image of one simulation state and the speed at that state."""

    time_s: float  # loop.time_s of the state
    rgb: np.ndarray  # (H, W, 3) uint8
    speed_mps: float


def annotate_frame(rgb: np.ndarray, detections: tuple[Detection, ...] | list[Detection], *, time_s: float,
                   speed_kmh: float, brake: float, conf_threshold: float) -> np.ndarray:
    """Draw `detections` (pixel boxes in this image) and the speed/brake panel on a copy of `rgb`.

    rgb: (H, W, 3) uint8 RGB. Returns (H, W, 3) uint8 in BGR order, ready for cv2.VideoWriter.
    """
    bgr = np.ascontiguousarray(rgb[..., ::-1])
    for det in detections:
        colour = _STOP_BOX_BGR if det.class_name == STOP_CLASS else _OTHER_BOX_BGR
        acted_on = det.confidence >= conf_threshold
        x0, y0, x1, y1 = (int(round(v)) for v in det.box_xyxy_px)
        cv2.rectangle(bgr, (x0, y0), (x1, y1), colour, 2 if acted_on else 1)
        label = f"{det.class_name} {det.confidence:.2f}"
        (text_w, text_h), baseline = cv2.getTextSize(label, _FONT, _FONT_SCALE, 1)
        # The label sits above the box, or inside it when the box touches the top edge.
        top = y0 - text_h - baseline - 2 if y0 - text_h - baseline - 2 >= 0 else y0
        cv2.rectangle(bgr, (x0, top), (x0 + text_w + 4, top + text_h + baseline + 2), colour, cv2.FILLED)
        cv2.putText(bgr, label, (x0 + 2, top + text_h + 1), _FONT, _FONT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
    _draw_panel(bgr, time_s, speed_kmh, brake)
    return bgr


def _draw_panel(bgr: np.ndarray, time_s: float, speed_kmh: float, brake: float) -> None:
    panel_w, panel_h = _PANEL_SIZE_PX
    region = bgr[:panel_h, :panel_w]
    region[:] = (region * (1 - _PANEL_OPACITY)).astype(np.uint8)  # darken, so the text reads on sky
    lines = (f"t      {time_s:6.2f} s", f"speed {speed_kmh:6.1f} km/h", f"brake  {brake:5.2f}")
    for row, text in enumerate(lines):
        cv2.putText(bgr, text, (8, 18 + 20 * row), _FONT, _FONT_SCALE, _TEXT_BGR, 1, cv2.LINE_AA)
    bar_x0, bar_x1, bar_y = 120, panel_w - 8, 18 + 20 * 2
    cv2.rectangle(bgr, (bar_x0, bar_y - 10), (bar_x1, bar_y), _TEXT_BGR, 1)
    filled_x = bar_x0 + int(round((bar_x1 - bar_x0) * min(max(brake, 0.0), 1.0)))
    if filled_x > bar_x0:
        cv2.rectangle(bgr, (bar_x0, bar_y - 10), (filled_x, bar_y), _BRAKE_BAR_BGR, cv2.FILLED)


def _frames_in(path: Path) -> int:
    """The frames an MP4 file holds, as its index counts them (0 when it cannot be opened)."""
    with c_stderr_silenced():  # FFmpeg's own "moov atom not found" on a cut file
        capture = cv2.VideoCapture(str(path))
    try:
        return int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) if capture.isOpened() else 0
    finally:
        capture.release()


class VideoRecorder(StepRecorder):
    """Writes the front camera of one `ClosedLoop` run to `path` (.mp4); attach before the first step."""

    def __init__(self, loop: ClosedLoop, path: str | os.PathLike) -> None:
        self._check_unstarted(loop)
        self._attach(loop)
        self._path = Path(path)
        if self._path.suffix.lower() != ".mp4":
            raise ConfigError(f"--mp4 expects a path ending in .mp4, got '{self._path}'")
        self._conf_threshold = loop.config.policy.conf_threshold
        self._last_brake = 0.0
        self.frames_written = 0
        intrinsics = loop.rig.intrinsics(CAMERA)
        self._size_px = (intrinsics.width_px, intrinsics.height_px)
        fps = 1.0 / loop.config.loop.control_dt_s

        self._path.parent.mkdir(parents=True, exist_ok=True)
        # A unique hidden name beside `path` (same file system, so the rename is atomic), which a
        # later write of `path` removes if this process is killed; it ends in .mp4 because
        # OpenCV picks the container from the extension.
        self._tmp_path = temporary_path(self._path, ".mp4")
        self._writer = cv2.VideoWriter(str(self._tmp_path), cv2.VideoWriter_fourcc(*FOURCC), fps, self._size_px)
        try:
            if not self._writer.isOpened():
                raise AvsimError(f"cannot write {self._path}: OpenCV could not open an '{FOURCC}' MP4 writer "
                                 "(is the directory writable, and does this OpenCV build include an MP4 encoder?)")
            self._pending = self._capture()  # the sensing-time state of step 0
        except BaseException:
            self.abort()
            raise

    def _step(self, frame: _Frame, record: StepRecord) -> None:
        """Write the frame captured at `record`'s sensing time, annotated; called by `StepRecorder.on_step`."""
        detections = tuple(d for d in record.detections if d.camera == CAMERA)
        self._write(frame, detections, record.brake)
        self._last_brake = record.brake

    def _finish(self) -> None:
        """Write the final state's frame, finish the file and move it to `path`; called by `StepRecorder.close`."""
        self._write(self._pending, (), self._last_brake)  # no perception ran on the final state
        self._writer.release()
        if not self._tmp_path.is_file() or self._tmp_path.stat().st_size == 0:
            raise AvsimError(f"cannot write {self._path}: the '{FOURCC}' encoder produced no data")
        # OpenCV's writer reports no failed write (a full disk, a file-size limit): it logs a warning
        # and goes on, leaving a cut file. So the file is read back: every frame must be in it.
        readable = _frames_in(self._tmp_path)
        if readable != self.frames_written:
            raise OutputError(f"cannot write {self._path}: {readable} of its {self.frames_written} frames reached the "
                              "file (a full disk or a file-size limit?)")
        os.replace(self._tmp_path, self._path)

    def _discard(self) -> None:
        """Stop recording and delete the partial file; `path` is left untouched."""
        self._writer.release()
        self._tmp_path.unlink(missing_ok=True)


    def _capture(self) -> _Frame:
        loop = self._loop
        return _Frame(time_s=loop.time_s, rgb=loop.rig.render_rgb(loop.data, CAMERA), speed_mps=loop.vehicle.speed_mps())

    def _write(self, frame: _Frame, detections: tuple[Detection, ...], brake: float) -> None:
        bgr = annotate_frame(frame.rgb, detections, time_s=frame.time_s, speed_kmh=frame.speed_mps * 3.6,
                             brake=brake, conf_threshold=self._conf_threshold)
        self._writer.write(bgr)
        self.frames_written += 1
