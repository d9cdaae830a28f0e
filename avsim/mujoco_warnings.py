"""MuJoCo's own warning printout, kept off the command line's one-line errors.

MuJoCo prints "WARNING: Nan, Inf or huge value in QACC ... The simulation is unstable" to the
terminal as it meets a diverging state, several lines before avsim's loop stops the run with a
one-line `PhysicsError`. The loop does not need the printout: it reads the same events from
`MjData.warning`'s counters. The command line (`avsim.cli`) therefore routes MuJoCo's warnings
to the debug log instead; the Python API leaves MuJoCo's default alone.
"""

from __future__ import annotations

import logging

_LOG = logging.getLogger("avsim.mujoco")


def route_mujoco_warnings_to_log() -> None:
    """Send MuJoCo's warnings to the `avsim.mujoco` logger (debug level). Import MuJoCo only
    after the renderer is chosen (`avsim.sensors.gl_backend.check_gl_backend`)."""
    import mujoco

    mujoco.set_mju_user_warning(lambda message: _LOG.debug("MuJoCo: %s", message))
