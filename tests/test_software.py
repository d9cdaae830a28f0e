"""What a batch's manifest says it ran on: the versions, and what the default precision ran as."""

from __future__ import annotations

import mujoco
import torch

from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.sensors import gl
from avsim.software import NO_GL, software_versions


def test_the_versions_are_the_running_libraries_and_auto_is_what_it_runs_as_here():
    versions = software_versions()
    assert versions["mujoco"] == mujoco.__version__ and versions["torch"] == torch.__version__
    assert versions["precision_auto"] == auto_arithmetic()


def test_auto_is_recorded_as_fp32_on_a_cpu_without_bf16(monkeypatch):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: False)
    assert software_versions()["precision_auto"] == "fp32"


def test_the_gl_that_draws_the_frames_is_recorded_by_its_renderer_and_version(monkeypatch):
    gl._gl_info.cache_clear()  # read afresh from this process's GL (it is the real one: nothing patches it here)
    info = gl._gl_info()
    assert info is not None  # the tests render through EGL (or OSMesa)
    assert software_versions()["gl"] == f"{info.renderer}, OpenGL {info.version}"
    assert info.renderer != "?" and info.version[0].isdigit()
    # Where no context starts here (a Ray cluster's runs render on its machines), it says so.
    monkeypatch.setattr(gl, "_gl_info", lambda: None)
    assert software_versions()["gl"] == NO_GL
