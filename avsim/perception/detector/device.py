"""The torch device a training or evaluation run asks for, checked before any work.

`torch.device("cuda")` succeeds on a CPU-only build and fails only at the first `.to()`,
deep in the run; `check_device` refuses it up front in one line that names what to install.
"""

from __future__ import annotations

import torch

from avsim.errors import ConfigError

CUDA_INSTALL = ("install a CUDA build of torch (pip install torch --index-url https://download.pytorch.org/whl/cu128, "
                "on a machine with an NVIDIA driver), or use --device cpu")


def check_device(name: str, flag: str = "--device") -> torch.device:
    """The torch.device `name` names, or a one-line ConfigError when it is not a device name or
    this build of torch, or this machine, lacks it."""
    try:
        device = torch.device(name)
    except (RuntimeError, TypeError):
        raise ConfigError(f"{flag} '{name}' is not a torch device; use cpu, cuda, cuda:N or mps") from None
    if device.type == "cpu":
        return device
    if device.type == "cuda":
        if torch.version.cuda is None:
            raise ConfigError(f"{flag} {name}: this torch build ({torch.__version__}) has no CUDA; {CUDA_INSTALL}")
        if not torch.cuda.is_available():
            raise ConfigError(f"{flag} {name}: torch has CUDA {torch.version.cuda} but sees no GPU (check the NVIDIA "
                              f"driver and CUDA_VISIBLE_DEVICES), or use --device cpu")
        if device.index is not None and device.index >= torch.cuda.device_count():
            raise ConfigError(f"{flag} {name}: this machine has {torch.cuda.device_count()} CUDA device(s); "
                              f"use cuda:0 .. cuda:{torch.cuda.device_count() - 1}")
        return device
    if device.type == "mps":
        if not torch.backends.mps.is_available():
            raise ConfigError(f"{flag} {name}: Apple's MPS is not available here (it needs macOS on Apple silicon "
                              f"and a torch build with MPS); use --device cpu")
        return device
    raise ConfigError(f"{flag} '{name}': avsim trains on cpu, cuda or mps, not {device.type}")
