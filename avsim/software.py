"""What software, arithmetic and GL a batch ran on, for its manifest (`versions`).

A config holds `perception.detector_precision = "auto"` (and `coco_precision`, `yolo_precision`) as
given, so that its hash, and a resumed batch, do not depend on the CPU; what "auto" ran as is a
property of the machine, the same for every network, and is recorded here beside the library versions.
So is the GL that drew the frames (`gl`): a frame is a function of the state on one GL, and another GL or
another Mesa may draw some of its pixels differently.
"""

from __future__ import annotations

import os
import platform

import mujoco
import numpy
import torch

from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.sensors.gl import gl_description

NO_GL = "none in this process"


def software_versions() -> dict[str, str]:
    """Python, MuJoCo, torch and numpy versions, the machine, `precision_auto`: the arithmetic
    ("fp32" or "bf16") that a network's precision "auto" (the own detector's and the COCO CenterNet's
    default) runs as here, and `gl`: this machine's GL renderer and version (NO_GL where no context starts
    here; a Ray cluster's runs render on its own machines)."""
    return {"python": platform.python_version(), "mujoco": mujoco.__version__, "torch": torch.__version__,
            "numpy": numpy.__version__, "machine": f"{platform.machine()}, {os.cpu_count()} cores",
            "precision_auto": auto_arithmetic(), "gl": gl_description() or NO_GL}
