"""avsim: a closed-loop autonomous-vehicle simulator on MuJoCo for stop-sign attacks and defences."""

import os

# MuJoCo picks its OpenGL backend when it is first imported, so the default must be
# set before any avsim module imports mujoco. A user's own MUJOCO_GL (e.g. osmesa) wins.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
