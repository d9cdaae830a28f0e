"""What libraries print on their own, kept off the command line's one-line messages.

- MuJoCo prints "WARNING: Nan, Inf or huge value in QACC ... The simulation is unstable" as it
  meets a diverging state, several lines before avsim's loop stops the run with a one-line
  `PhysicsError`. The loop does not need the printout: it reads the same events from
  `MjData.warning`'s counters. `route_mujoco_warnings_to_log` sends them to the debug log.
- rerun's Rust core logs its file writer's failure (a full disk) in three coloured lines before
  avsim reports it as one `OutputError` (`avsim.recording.rerun_log`). `quiet_rust_logs` turns
  that logging off unless the user set RUST_LOG.
- OpenCV's video writer logs "Failed to write frame" for every frame a full disk refuses, and
  goes on; avsim reads the file back and reports it as one `OutputError`
  (`avsim.recording.video`). `quiet_opencv_logs` keeps OpenCV to its errors.

The command line (`avsim.cli`) calls all three; the Python API leaves the libraries' defaults alone.
"""

from __future__ import annotations

import logging
import os

_LOG = logging.getLogger("avsim.mujoco")


def route_mujoco_warnings_to_log() -> None:
    """Send MuJoCo's warnings to the `avsim.mujoco` logger (debug level). Import MuJoCo only
    after the renderer is chosen (`avsim.sensors.gl_backend.check_gl_backend`)."""
    import mujoco

    mujoco.set_mju_user_warning(lambda message: _LOG.debug("MuJoCo: %s", message))


def quiet_opencv_logs() -> None:
    """OpenCV's own log at errors only (its warnings repeat once a frame for one failed file)."""
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)


def quiet_rust_logs() -> None:
    """RUST_LOG=off for rerun (read when it first logs; worker processes inherit it), unless set."""
    os.environ.setdefault("RUST_LOG", "off")
