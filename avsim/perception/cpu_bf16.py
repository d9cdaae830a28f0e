"""Whether this CPU runs bfloat16 convolutions, for the networks that offer a bf16 precision.

oneDNN has bf16 convolution kernels on x86 CPUs with AVX-512 (BW, VL and DQ; native dot products
with AVX-512 BF16 or AMX) or AVX-NE-CONVERT. Elsewhere torch would still run bf16, through slow
reference code, so a bf16 setting there is refused rather than quietly slow. The own detector's
default, "auto", is bf16 where the kernels exist and fp32 elsewhere (`detector_arithmetic`).
"""

from __future__ import annotations

import torch

from avsim.config import DETECTOR_PRECISIONS
from avsim.errors import ConfigError


def onednn_runs_bf16() -> bool:
    """True where oneDNN has bf16 convolution kernels for this CPU."""
    return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


def require_bf16(setting: str) -> None:
    """A one-line ConfigError naming `setting` (e.g. "perception.coco_precision") and its fix
    where this CPU has no bf16 kernels."""
    if not onednn_runs_bf16():
        raise ConfigError(f"{setting} = bf16 needs a CPU on which oneDNN runs bfloat16 (AVX-512 BW, VL and DQ, "
                          f"or AVX-NE-CONVERT), and this one has none; set {setting}=fp32")


def detector_arithmetic(precision: str) -> str:
    """The arithmetic ("fp32" or "bf16") that `perception.detector_precision = precision` runs as on this
    CPU: "auto" is bf16 where oneDNN runs it, else fp32; "bf16" on a CPU without it is a one-line ConfigError."""
    if precision not in DETECTOR_PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(DETECTOR_PRECISIONS)}, got {precision!r}")
    if precision == "auto":
        return "bf16" if onednn_runs_bf16() else "fp32"
    if precision == "bf16":
        require_bf16("perception.detector_precision")
    return precision
