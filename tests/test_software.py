"""What a batch's manifest says it ran on: the versions, and what the default precision ran as."""

from __future__ import annotations

import mujoco
import torch

from avsim.machine import cpu_model
from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.sensors import gl
from avsim.software import NO_GL, differences, software_versions, versions_sentence


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


def test_the_instruction_set_of_torchs_kernels_is_recorded():
    assert software_versions()["cpu_capability"] == torch.backends.cpu.get_cpu_capability()


def test_the_cpu_model_is_recorded():
    assert software_versions()["cpu"] == cpu_model()


HERE = {"python": "3.11.2", "mujoco": "4.0.0", "torch": "2.13.0", "numpy": "2.3.0", "machine": "x86_64, 2 cores",
        "cpu": "AMD EPYC 7B13", "cpu_capability": "AVX2", "precision_auto": "fp32", "gl": "llvmpipe, OpenGL 4.5 Mesa 22.3.6"}


def test_a_node_differs_only_in_what_decides_a_runs_numbers():
    twin = {"node": "10.0.0.2", **HERE, "machine": "x86_64, 64 cores", "python": "3.11.9"}  # neither decides a number
    other_gl = {"node": "10.0.0.3", **HERE, "gl": "NVIDIA H200, OpenGL 4.6"}
    wider = {"node": "10.0.0.4", **HERE, "cpu_capability": "AVX512", "precision_auto": "bf16"}
    silent = {"node": "10.0.0.5", "error": "no answer within 120 s"}
    newer = {"node": "10.0.0.6", **HERE, "cpu": "AMD EPYC 9B14"}  # same instruction set, another CPU
    assert differences(HERE, [twin]) == []
    assert differences(HERE, [twin, other_gl, wider, silent, newer]) == [
        "10.0.0.3 runs gl 'NVIDIA H200, OpenGL 4.6' (here 'llvmpipe, OpenGL 4.5 Mesa 22.3.6')",
        "10.0.0.4 runs cpu_capability 'AVX512' (here 'AVX2'), precision_auto 'bf16' (here 'fp32')",
        "10.0.0.5 did not say what it runs (no answer within 120 s)",
        "10.0.0.6 runs cpu 'AMD EPYC 9B14' (here 'AMD EPYC 7B13')"]


def test_a_reports_versions_sentence_names_the_cluster_where_the_runs_ran_on_one():
    assert versions_sentence(HERE) == "Versions: " + ", ".join(f"{k} {v}" for k, v in HERE.items()) + "."
    alike = versions_sentence(HERE, [{"node": "10.0.0.2", **HERE}, {"node": "10.0.0.3", **HERE}])
    assert alike.startswith("Versions of this machine, which sent the runs out: python 3.11.2, ")
    assert alike.endswith("They ran on 2 Ray nodes (manifest.json's cluster_nodes): each with these versions.")
    assert versions_sentence(HERE, []).endswith("They ran on a Ray cluster that had no node with CPUs when asked, so "
                                                 "what they ran on is not recorded.")
    unlike = versions_sentence(HERE, [{"node": "10.0.0.3", **HERE, "gl": "NVIDIA"}])
    assert unlike.endswith("They ran on 1 Ray node (manifest.json's cluster_nodes): 10.0.0.3 runs gl 'NVIDIA' "
                           "(here 'llvmpipe, OpenGL 4.5 Mesa 22.3.6').")
