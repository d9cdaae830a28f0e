"""Whether this CPU runs bfloat16 convolutions, and what each network's precision setting runs as here.

oneDNN has bf16 convolution kernels on x86 CPUs with AVX-512 (BW, VL and DQ; native dot products
with AVX-512 BF16 or AMX) or AVX-NE-CONVERT. Elsewhere (an AVX2 CPU such as AMD's Zen 3) torch would
still run bf16, through slow reference code, so an explicit "bf16" there is refused rather than quietly
slow. "auto" (the own detector's and the COCO CenterNet's default) is bf16 where the kernels exist and
fp32 elsewhere (`arithmetic`), so a default run works on every CPU; the same config and seed then give
the same result bit for bit only on CPUs that run the same arithmetic.
"""

from __future__ import annotations

import torch

from avsim.config import ARITHMETICS, PRECISIONS
from avsim.errors import ConfigError


def onednn_runs_bf16() -> bool:
    """True where oneDNN has bf16 convolution kernels for this CPU."""
    return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


def require_bf16(setting: str) -> None:
    """A one-line ConfigError naming `setting` (e.g. "perception.coco_precision") and its fix
    where this CPU has no bf16 kernels."""
    if not onednn_runs_bf16():
        raise ConfigError(f"{setting} = bf16 needs a CPU on which oneDNN runs bfloat16 (AVX-512 BW, VL and DQ, "
                          f"or AVX-NE-CONVERT), and this one has none; set {setting}=auto or fp32")


def arithmetics_here() -> tuple[str, ...]:
    """The arithmetics a network can run in on this CPU: fp32 everywhere, bf16 where oneDNN runs it."""
    return ARITHMETICS if onednn_runs_bf16() else ("fp32",)


def auto_arithmetic() -> str:
    """What a precision of "auto" runs as on this CPU: "bf16" where oneDNN runs it, else "fp32"."""
    return "bf16" if onednn_runs_bf16() else "fp32"


def arithmetic(precision: str, setting: str) -> str:
    """The arithmetic ("fp32" or "bf16") that `setting = precision` (e.g. "perception.coco_precision" =
    "auto") runs as on this CPU: "auto" is bf16 where oneDNN runs it, else fp32; "bf16" on a CPU without
    it is a one-line ConfigError naming `setting`."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    if precision == "auto":
        return auto_arithmetic()
    if precision == "bf16":
        require_bf16(setting)
    return precision


def detector_arithmetic(precision: str) -> str:
    """`arithmetic` of `perception.detector_precision = precision`."""
    return arithmetic(precision, "perception.detector_precision")
