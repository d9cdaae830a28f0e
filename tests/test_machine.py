"""The CPU model as the machine names it."""

from __future__ import annotations

import platform

from avsim.machine import cpu_model


def test_the_cpu_model_is_read_from_proc_cpuinfo_and_falls_back_without_it(tmp_path, monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC 9B14\n\n"
                       "processor\t: 1\nmodel name\t: AMD EPYC 9B14\n")
    assert cpu_model(str(cpuinfo)) == "AMD EPYC 9B14"
    monkeypatch.setattr(platform, "processor", lambda: "arm")
    assert cpu_model(str(tmp_path / "missing")) == "arm"
    cpuinfo.write_text("processor\t: 0\nmodel name\t:\n")  # an empty name is no name
    assert cpu_model(str(cpuinfo)) == "arm"
    monkeypatch.setattr(platform, "processor", lambda: "")
    assert cpu_model(str(cpuinfo)) == "unknown"
