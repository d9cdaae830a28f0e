"""The machine's CPU model by name: a leaf module, so that a batch's manifest (`avsim.software`) and a training's
per-epoch record (`avsim.perception.detector.train`) can both say where their arithmetic ran."""

from __future__ import annotations

import platform


def cpu_model(cpuinfo_path: str = "/proc/cpuinfo") -> str:
    """The CPU's model as Linux names it (the first "model name" in /proc/cpuinfo, e.g. "AMD EPYC 9B14"),
    else what `platform.processor()` says, else "unknown"."""
    try:
        with open(cpuinfo_path, encoding="utf-8", errors="replace") as cpuinfo:
            for line in cpuinfo:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and value.strip():
                    return value.strip()
    except OSError:
        pass  # not Linux: fall back below
    return platform.processor() or "unknown"
