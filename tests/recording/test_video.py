"""The front-camera MP4 of a run (`avsim run --mp4`), read back with cv2.VideoCapture."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import avsim.loop
from avsim import cli
from avsim.errors import PhysicsError
from avsim.loop import ClosedLoop
from avsim.perception.base import Detection
from avsim.recording.video import VideoRecorder, annotate_frame
from helpers import make_config

WIDTH_PX, HEIGHT_PX = 640, 480  # the default camera
# Close enough to the sign that the oracle sees it from the first step; the car stops in ~1.5 s.
SHORT_RUN_SETS = ["--set", "scenario.start_dist_m=35", "--set", "scenario.start_speed_kmh=40"]


def _read_frames(path) -> list[np.ndarray]:
    capture = cv2.VideoCapture(str(path))
    assert capture.isOpened()
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    return frames


def test_cli_mp4_has_one_frame_per_step_plus_the_final_state(tmp_path):
    out = tmp_path / "out"
    # --rrd and --mp4 together: both recorders hook the same run.
    code = cli.main(["run", "--perception", "oracle", *SHORT_RUN_SETS, "--mp4", str(out / "run.mp4"),
                     "--rrd", str(out / "run.rrd"), "--json", str(out / "run.json")])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == ["run.json", "run.mp4", "run.rrd"]  # no temp files left
    result = json.loads((out / "run.json").read_text())
    steps = round(result["sim_time_s"] / 0.05)
    assert steps > 10  # the run did drive and brake
    frames = _read_frames(out / "run.mp4")
    assert len(frames) == steps + 1
    assert frames[0].shape == (HEIGHT_PX, WIDTH_PX, 3)
    assert cv2.VideoCapture(str(out / "run.mp4")).get(cv2.CAP_PROP_FPS) == pytest.approx(20.0)


def test_cli_error_mid_run_leaves_no_file(tmp_path, capsys, monkeypatch):
    real_step = ClosedLoop.step

    def _diverge_on_third_step(self):
        if len(self.records) == 2:
            raise PhysicsError("physics diverged at t = 0.10 s (test)")
        return real_step(self)

    monkeypatch.setattr(avsim.loop.ClosedLoop, "step", _diverge_on_third_step)
    code = cli.main(["run", "--perception", "oracle", *SHORT_RUN_SETS, "--mp4", str(tmp_path / "run.mp4"),
                     "--rrd", str(tmp_path / "run.rrd"), "--json", str(tmp_path / "run.json")])
    assert code == 3
    assert "diverged" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_recorder_error_inside_the_block_leaves_no_file_and_keeps_an_old_one(tmp_path):
    path = tmp_path / "run.mp4"
    path.write_bytes(b"an earlier video")
    loop = ClosedLoop(make_config(scenario={"start_dist_m": 35.0, "start_speed_kmh": 40.0}))
    try:
        with pytest.raises(RuntimeError, match="interrupted"):
            with VideoRecorder(loop, path) as video:
                for _ in range(2):
                    video.on_step(loop, loop.step())
                raise RuntimeError("interrupted")
    finally:
        loop.close()
    assert [p.name for p in tmp_path.iterdir()] == ["run.mp4"]
    assert path.read_bytes() == b"an earlier video"


def test_mp4_path_must_end_in_mp4(tmp_path, capsys):
    code = cli.main(["run", "--perception", "oracle", *SHORT_RUN_SETS, "--mp4", str(tmp_path / "run.avi")])
    assert code == 2
    assert ".mp4" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_annotate_frame_draws_the_box_label_and_panel():
    rgb = np.full((HEIGHT_PX, WIDTH_PX, 3), 128, np.uint8)
    stop = Detection("stop_sign", 0.93, (300.0, 200.0, 340.0, 240.0), "front")
    bgr = annotate_frame(rgb, [stop], time_s=1.0, speed_kmh=50.0, brake=0.5, conf_threshold=0.5)
    assert bgr.shape == rgb.shape and bgr.dtype == np.uint8
    assert tuple(bgr[220, 300]) == (40, 40, 255)  # the box's left edge, red in BGR
    assert tuple(bgr[220, 320]) == (128, 128, 128)  # its inside is untouched
    assert (bgr[185:199, 300:340] != 128).any()  # the label above the box
    assert bgr[5:60, 5:180].mean() < 128  # the darkened speed/brake panel
    assert (rgb == 128).all()  # the input is not drawn on


def test_an_mp4_that_a_full_disk_cut_is_refused_in_one_line_and_not_kept(tmp_path):
    """OpenCV's writer reports no failed write; the recorder reads the file back. A file-size limit
    (RLIMIT_FSIZE, which Python meets as EFBIG: it ignores SIGXFSZ) stands in for a full disk."""
    import resource

    from avsim.errors import OutputError

    loop = ClosedLoop(make_config(scenario={"start_dist_m": 35.0, "start_speed_kmh": 40.0}))
    limits = resource.getrlimit(resource.RLIMIT_FSIZE)
    try:
        with pytest.raises(OutputError, match=r"cannot write .*run\.mp4: \d+ of its 4 frames reached the file"):
            with VideoRecorder(loop, tmp_path / "run.mp4") as video:
                resource.setrlimit(resource.RLIMIT_FSIZE, (8_000, limits[1]))
                for _ in range(3):
                    video.on_step(loop, loop.step())
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, limits)
        loop.close()
    assert list(tmp_path.iterdir()) == []
