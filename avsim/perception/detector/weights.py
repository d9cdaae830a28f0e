"""Detector checkpoints: atomic save, weights-only load, one-line errors.

A checkpoint is a `torch.save`d dict of tensors and plain Python values only, so it
loads with `torch.load(weights_only=True)` (no code runs on load):
  format     "avsim-sign-detector", version 1
  model      the deployable state_dict (the EMA weights when training used EMA)
  meta       {"arch": build_detector kwargs, "input_size": [W_in, H_in],
              "class_names": [...], "seed": int, "epochs": int, ...}
  epoch      epochs completed
  optimizer  the optimiser state_dict (or None)
  train_state  what `train(resume=True)` needs besides (raw weights, EMA, step, history)
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path
from typing import Any

import torch
from torch import nn

from avsim.errors import AvsimError
from avsim.file_kinds import special_file_kind
from avsim.outputs import temporary_path
from avsim.perception.detector.model import SignDetector, build_detector

# The shipped weights, trained by `avsim detector train` on `avsim detector make-data` renders.
SHIPPED_WEIGHTS = Path(__file__).resolve().parents[3] / "models" / "sign_detector.pt"
FORMAT = "avsim-sign-detector"
VERSION = 1
TRAIN_HINT = "`avsim detector train` (python -m avsim.perception.detector.train --data DIR --out PATH)"


def resolve_weights_path(weights_path: str) -> Path:
    """The configured weights file; an empty string means the shipped weights."""
    return Path(weights_path) if weights_path else SHIPPED_WEIGHTS


class WeightsError(AvsimError):
    """Detector weights that are missing, corrupt, or not avsim detector weights."""


def _one_line(text: str, limit: int = 100) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def _corrupt(path: Path, reason: str) -> WeightsError:
    return WeightsError(f"detector weights {path} are corrupt or not avsim detector weights ({_one_line(reason)}); "
                        f"retrain with {TRAIN_HINT}")


_PLAIN = (str, int, float, bool, type(None))


def _check_plain(value: Any, where: str) -> None:
    """Raise TypeError unless `value` holds only tensors and plain Python values (weights-only loadable)."""
    if isinstance(value, dict):
        for key, item in value.items():
            if type(key) not in _PLAIN:
                raise TypeError(f"{where} has a key of type {type(key).__name__}; use str or int")
            _check_plain(item, f"{where}[{key!r}]")
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            _check_plain(item, f"{where}[{i}]")
    elif not (type(value) in _PLAIN or isinstance(value, torch.Tensor)):
        raise TypeError(f"{where} is a {type(value).__name__}; checkpoints hold only tensors and plain values")


def save_checkpoint(path: str | Path, model: nn.Module, optimizer: torch.optim.Optimizer | None, epoch: int,
                    meta: dict[str, Any], train_state: dict[str, Any] | None = None) -> Path:
    """Write a checkpoint atomically (temporary file, then `os.replace`); returns the path.

    model: the deployable weights; meta: plain values only (see the module docstring).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "model": model.state_dict(),
        "meta": meta,
        "epoch": int(epoch),
        "optimizer": optimizer.state_dict() if optimizer is not None else None,
        "train_state": train_state or {},
    }
    _check_plain(payload, "checkpoint")
    tmp = temporary_path(path)  # removed by the next save if this process is killed mid-write
    try:
        torch.save(payload, tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """The checkpoint dict, checked to be ours; raises WeightsError if missing or unreadable."""
    path = Path(path)
    if path.is_dir():
        raise WeightsError(f"detector weights {path} is a folder; name the weights file in it (e.g. {path / 'sign_detector.pt'})")
    if kind := special_file_kind(path):  # torch.load would read a device until memory runs out
        raise WeightsError(f"detector weights {path} is {kind}, not a regular file; name a weights file")
    if not path.is_file():
        raise WeightsError(f"detector weights {path} are missing; train them with {TRAIN_HINT} (see docs/perception.md)")
    try:
        checkpoint = torch.load(path, weights_only=True, map_location="cpu")
    except Exception as exc:  # torch.load fails in many ways on garbage (pickle, zip, EOF, key errors)
        raise _corrupt(path, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'unreadable'}") from exc
    if not isinstance(checkpoint, dict) or checkpoint.get("format") != FORMAT:
        raise _corrupt(path, f"no '{FORMAT}' format tag")
    if checkpoint.get("version") != VERSION:
        raise _corrupt(path, f"format version {checkpoint.get('version')!r}, this code reads {VERSION}")
    meta = checkpoint.get("meta")
    if not isinstance(checkpoint.get("model"), dict) or not isinstance(meta, dict) or not isinstance(meta.get("arch"), dict):
        raise _corrupt(path, "no model state or architecture")
    return checkpoint


def load_weights(path: str | Path) -> tuple[SignDetector, dict[str, Any]]:
    """(model in eval mode, not fused; meta) from a checkpoint; raises WeightsError if unusable."""
    checkpoint = load_checkpoint(path)
    meta = checkpoint["meta"]
    try:
        model = build_detector(**meta["arch"])
        model.load_state_dict(checkpoint["model"], strict=True)
    except (TypeError, ValueError, RuntimeError, KeyError) as exc:
        raise _corrupt(Path(path), f"architecture does not match: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from exc
    return model.eval(), meta


def _where(ran_on: dict[str, Any]) -> str:
    """One epoch's `ran_on` in words: "CPU (ISA kernels, oneDNN cap X, N threads)"."""
    threads = ran_on.get("torch_threads", "?")
    return (f"{ran_on.get('cpu', '?')} ({ran_on.get('cpu_capability', '?')} kernels, oneDNN cap "
            f"{ran_on.get('onednn_max_cpu_isa', '?')}, {threads} thread{'' if threads == 1 else 's'})")


def training_sentence(meta: dict[str, Any]) -> str:
    """One sentence on how a checkpoint's weights were trained, from its `meta`: epochs, seed, data, and where
    each epoch's arithmetic ran (the `ran_on` that training records since 2026-12-07), or that it is not recorded.

    The same data and seed on other arithmetic give other weights (docs/perception.md), so a report that scores
    weights names the training they are. `meta` comes from a file: any field may be missing or malformed.
    """
    history = meta.get("history") if isinstance(meta.get("history"), list) else []
    data = f" of {meta['data_dir']}" if isinstance(meta.get("data_dir"), str) else ""
    sentence = (f"Trained for {len(history) or meta.get('epochs', '?')} epochs with seed {meta.get('seed', '?')} on "
                f"{meta.get('train_images', '?')} images{data}")
    places = [entry.get("ran_on") if isinstance(entry, dict) else None for entry in history]
    if not places or any(not isinstance(place, dict) for place in places):
        return (sentence + "; where its arithmetic ran (CPU, kernels, threads) is not recorded, and the same data and "
                "seed give these weights only on the same arithmetic.")
    # One clause per stretch of epochs on the same arithmetic, in order (a training resumed elsewhere and back
    # ran on three).
    stretches = [place for place, _ in itertools.groupby(places)]
    return sentence + ", on " + ", then on ".join(_where(place) for place in stretches) + "."


def export_weights(checkpoint_path: str | Path, out_path: str | Path) -> Path:
    """Write the deployable part of a training checkpoint (model weights and meta) to `out_path`.

    Drops the optimiser and training state, which are several times the size of the
    weights and only matter for `--resume`. Raises WeightsError if the checkpoint is unusable.
    """
    checkpoint_path = Path(checkpoint_path)
    model, meta = load_weights(checkpoint_path)
    checkpoint = load_checkpoint(checkpoint_path)
    return save_checkpoint(out_path, model, None, int(checkpoint["epoch"]), meta)
