"""What a batch's manifest says it ran on: the versions, and what the default precision ran as."""

from __future__ import annotations

import mujoco
import torch

from avsim.perception.cpu_bf16 import auto_arithmetic
from avsim.software import software_versions


def test_the_versions_are_the_running_libraries_and_auto_is_what_it_runs_as_here():
    versions = software_versions()
    assert versions["mujoco"] == mujoco.__version__ and versions["torch"] == torch.__version__
    assert versions["precision_auto"] == auto_arithmetic()


def test_auto_is_recorded_as_fp32_on_a_cpu_without_bf16(monkeypatch):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: False)
    assert software_versions()["precision_auto"] == "fp32"
