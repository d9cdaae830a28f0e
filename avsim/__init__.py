"""avsim: a closed-loop autonomous-vehicle simulator on MuJoCo for stop-sign attacks and defences."""

import os

# MuJoCo picks its OpenGL backend when it is first imported, so the default must be
# set before any avsim module imports mujoco. A user's own MUJOCO_GL (e.g. osmesa) wins.
os.environ.setdefault("MUJOCO_GL", "egl")

# PyTorch's OpenMP threads (libgomp) busy-wait 300,000 spins between parallel regions unless told
# otherwise, which assumes every thread owns a core. With two torch threads on two cores that other
# processes share (a sweep beside `avsim detector eval`, the test suite), a spinning thread holds the
# core its partner needs, and each operator's barrier waits for a time slice: `avsim detector eval`
# took 90 s instead of 8 beside one busy process. 1,000 spins is what libgomp itself falls back to when
# it knows it is oversubscribed; on a quiet machine it measured as fast as the default and used ~20 %
# less CPU (docs/performance.md). libgomp reads this once, when torch first loads it, so it is set
# here, before any avsim module imports torch. A user's own GOMP_SPINCOUNT or OMP_WAIT_POLICY wins.
if "OMP_WAIT_POLICY" not in os.environ:
    os.environ.setdefault("GOMP_SPINCOUNT", "1000")

__version__ = "0.1.0"
