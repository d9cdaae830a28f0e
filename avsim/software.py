"""What software, arithmetic and GL a batch ran on, for its manifest (`versions`).

A config holds `perception.detector_precision = "auto"` (and `coco_precision`, `yolo_precision`) as
given, so that its hash, and a resumed batch, do not depend on the CPU; what "auto" ran as is a
property of the machine, the same for every network, and is recorded here beside the library versions.
So is the GL that drew the frames (`gl`): a frame is a function of the state on one GL, and another GL or
another Mesa may draw some of its pixels differently. And so is the vector instruction set torch's CPU kernels use
here (`cpu_capability`, e.g. AVX2 or AVX512): fp32 convolutions may sum in another order on another one, so a score
may differ in its last bits. Two CPUs with the same instruction set can still differ: oneDNN picks its kernels by
the CPU's features beyond it (AMX tiles on recent Intel CPUs, AVX-512 BF16 dot products on AMD's Zen 4) and blocks
them by its caches, so the CPU's model (`cpu`) is recorded as well.
"""

from __future__ import annotations

import os
import platform

import mujoco
import numpy
import torch

from avsim.machine import cpu_model
from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.sensors.gl import gl_description

NO_GL = "none in this process"


def software_versions() -> dict[str, str]:
    """Python, MuJoCo, torch and numpy versions, the machine, `cpu_capability`: the instruction set torch's
    CPU kernels run on here, `precision_auto`: the arithmetic ("fp32" or "bf16") that a network's precision
    "auto" (the own detector's and the COCO CenterNet's default) runs as here, and `gl`: this machine's GL
    renderer and version (NO_GL where no context starts here). All of this machine: a Ray cluster's runs
    render and infer on its nodes (`avsim.experiments.ray_backend.cluster_nodes`)."""
    return {"python": platform.python_version(), "mujoco": mujoco.__version__, "torch": torch.__version__,
            "numpy": numpy.__version__, "machine": f"{platform.machine()}, {os.cpu_count()} cores",
            "cpu": cpu_model(), "cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "precision_auto": auto_arithmetic(), "gl": gl_description() or NO_GL}


# The versions that decide a run's numbers: where another machine differs from this one in one of them, its
# runs may differ in their last bits (the arithmetic, the kernels) or in pixels (the GL). "machine" names the
# core count too, which decides nothing; "python" decides nothing either. "cpu" may decide the last bits (the
# module docstring); a cluster of unlike CPUs is named as such, not proven to differ.
RESULT_DECIDING = ("mujoco", "torch", "numpy", "cpu", "cpu_capability", "precision_auto", "gl")


def differences(here: dict[str, str], nodes: list[dict[str, str]]) -> list[str]:
    """One phrase for each of `nodes` (a Ray cluster's: `avsim.experiments.ray_backend.node_versions`) that
    differs from `here` in a version that decides a run's numbers (RESULT_DECIDING), or that did not answer;
    [] where every node is this machine's twin."""
    phrases = []
    for node in nodes:
        if "error" in node:
            phrases.append(f"{node['node']} did not say what it runs ({node['error']})")
            continue
        differ = [f"{key} {node.get(key)!r} (here {here.get(key)!r})" for key in RESULT_DECIDING
                  if node.get(key) != here.get(key)]
        if differ:
            phrases.append(f"{node['node']} runs " + ", ".join(differ))
    return phrases


def versions_sentence(versions: dict[str, str], cluster_nodes: list[dict[str, str]] | None = None) -> str:
    """A report's sentence on what its runs ran on, from a manifest's `versions` and `cluster_nodes`."""
    here = ", ".join(f"{key} {value}" for key, value in versions.items())
    if cluster_nodes is None:
        return f"Versions: {here}."
    if not cluster_nodes:  # an autoscaling cluster with no CPU node yet when it was asked
        return (f"Versions of this machine, which sent the runs out: {here}. They ran on a Ray cluster that had no "
                "node with CPUs when asked, so what they ran on is not recorded.")
    phrases = differences(versions, cluster_nodes)
    nodes = f"{len(cluster_nodes)} Ray node{'s' if len(cluster_nodes) != 1 else ''}"
    alike = "each with these versions" if not phrases else "; ".join(phrases)
    return (f"Versions of this machine, which sent the runs out: {here}. They ran on {nodes} (manifest.json's "
            f"cluster_nodes): {alike}.")
