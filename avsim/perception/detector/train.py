"""Train the sign detector: AdamW, linear warm-up then cosine decay, EMA weights, resumable.

    python -m avsim.perception.detector.train --data DIR --out PATH --epochs N --seed S [--resume]

Order per step: lr(step) -> forward -> loss terms -> every term finite? (else stop with
TrainingError naming the term and step) -> backward -> clip grad norm -> AdamW step -> EMA.
Per epoch: a log line with each loss term, mAP@0.5 of the EMA weights on DIR/val.jsonl
(if present), then an atomic checkpoint to PATH holding the EMA (deployable) weights and
everything `resume=True` needs: raw weights, optimiser, EMA, step, history.

Determinism: the model init runs under `torch.manual_seed(seed)` inside
`torch.random.fork_rng()` (global RNG state untouched afterwards); the data order of epoch
e comes from a `torch.Generator` seeded from (seed, e), augmentation from (seed, e, index);
the learning rate is a pure function of the step. So the same seed gives the same weights,
and resuming after any epoch gives the same weights as an uninterrupted run, on the same
arithmetic: the CPU, the instruction set torch's and oneDNN's kernels use, and the thread count
decide the order in which the convolutions sum, and a change in the last bits grows over the
steps (measured on the shipped recipe: capping the kernels at AVX2, or one thread instead of two,
moves the logged loss by step 30). So each epoch's history entry records where it ran (`ran_on`).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.data import DataLoader
from tqdm import tqdm

from avsim.boundary import run_guarded
from avsim.errors import AvsimError, ConfigError, Interrupted
from avsim.machine import cpu_model
from avsim.outputs import check_declared_outputs
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.data import SignDataset, collate
from avsim.perception.detector.device import check_device
from avsim.perception.detector.ema import ModelEMA
from avsim.perception.ap import mean_ap
from avsim.perception.detector.train_args import INPUT_SIZE_MULTIPLE_PX, MAX_INPUT_SIDE_PX, add_train_arguments
from avsim.perception.detector.map50 import evaluate_map50
from avsim.perception.detector.loss import LossWeights, compute_loss
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE, build_detector
from avsim.perception.detector.weights import load_checkpoint, save_checkpoint
from avsim.validation import OneLineArgumentParser

LOSS_TERMS = ("obj", "cls", "box", "total")
RESUME_KEYS = ("arch", "input_size", "seed", "epochs", "batch_size", "lr")

__all__ = ["TrainingError", "evaluate_map50", "lr_at", "main", "train"]


class TrainingError(AvsimError):
    """Training diverged (a non-finite loss term)."""

    exit_code = 3


def lr_at(step: int, total_steps: int, base_lr: float, warmup_steps: int, min_lr_ratio: float) -> float:
    """Learning rate at optimiser step `step` (0-based): linear warm-up to base_lr, then cosine to base_lr * min_lr_ratio."""
    if step < warmup_steps:
        return base_lr * (step + 1) / warmup_steps
    progress = min(1.0, (step - warmup_steps) / max(1, total_steps - warmup_steps))
    return base_lr * (min_lr_ratio + (1.0 - min_lr_ratio) * 0.5 * (1.0 + math.cos(math.pi * progress)))


def _seed_for(*keys: int) -> int:
    return int(np.random.SeedSequence(list(keys)).generate_state(1)[0])


def _param_groups(model: nn.Module, weight_decay: float) -> list[dict[str, Any]]:
    """Weight decay on conv kernels only; none on BatchNorm parameters and biases."""
    decay = [p for p in model.parameters() if p.ndim > 1]
    no_decay = [p for p in model.parameters() if p.ndim <= 1]
    return [{"params": decay, "weight_decay": weight_decay}, {"params": no_decay, "weight_decay": 0.0}]


def _check_finite(losses: dict[str, torch.Tensor], epoch: int, step: int, lr: float) -> None:
    for name, value in losses.items():
        if not torch.isfinite(value):
            raise TrainingError(f"detector loss term '{name}' became {value.item()} at epoch {epoch} step {step}; "
                                f"lower the learning rate (now {lr:.2e}) or check the dataset boxes")


def ran_on(device: str) -> dict[str, Any]:
    """The arithmetic an epoch runs on here: the CPU's model, the instruction set of torch's CPU kernels
    (`cpu_capability`), oneDNN's cap on its own (`ONEDNN_MAX_CPU_ISA`, "unset" by default), torch's thread
    count and the device. Training gives the same weights bit for bit only where all of these are the same."""
    return {"cpu": cpu_model(), "cpu_capability": torch.backends.cpu.get_cpu_capability(),
            "onednn_max_cpu_isa": os.environ.get("ONEDNN_MAX_CPU_ISA", "unset"),
            "torch_threads": torch.get_num_threads(), "device": str(device)}


def _check_resumable(meta: dict[str, Any], saved: dict[str, Any], path: Path) -> None:
    for key in RESUME_KEYS:
        if saved.get(key) != meta[key]:
            raise ConfigError(f"checkpoint {path} was trained with {key}={saved.get(key)!r}, not {meta[key]!r}; "
                              f"rerun with the same settings, or without --resume to start afresh")


def train(data_dir: str | Path, out_path: str | Path, epochs: int = 6, batch_size: int = 16, lr: float = 2e-3,
          seed: int = 0, resume: bool = False, input_size: tuple[int, int] = DEPLOY_INPUT_SIZE, log_every: int = 50,
          device: str = "cpu", *, overwrite: bool = False, width_mult: float = 1.0, depth: int = 1, act: str = "leaky_relu",
          weight_decay: float = 0.05, warmup_steps: int | None = None, min_lr_ratio: float = 0.05,
          ema_decay: float = 0.9995, grad_clip_norm: float = 10.0, loss_weights: LossWeights = LossWeights(),
          progress: bool = True) -> dict[str, Any]:
    """Train on DIR/train.jsonl, validate on DIR/val.jsonl, checkpoint to `out_path` every epoch.

    An existing `out_path` is continued (resume) or replaced (overwrite), and refused with neither,
    once the dataset (every label line and image file) has been checked and before any training.

    epochs: total epochs (also when resuming); lr: peak AdamW learning rate;
    input_size: (W_in, H_in), multiples of 32 up to 4096; log_every: steps between log lines (0: none);
    warmup_steps: None for min(1000, total_steps // 10).
    Returns {"out_path", "epochs", "history": per-epoch {"epoch", loss terms, "lr", "map50", "mAP50", "seconds"}}.
    """
    if epochs < 1 or batch_size < 1 or lr <= 0 or log_every < 0:
        raise ConfigError(f"need epochs >= 1, batch_size >= 1, lr > 0, log_every >= 0; got {epochs}, {batch_size}, {lr}, {log_every}")
    if len(input_size) != 2 or any(int(v) % INPUT_SIZE_MULTIPLE_PX or not INPUT_SIZE_MULTIPLE_PX <= int(v) <= MAX_INPUT_SIDE_PX
                                   for v in input_size):
        raise ConfigError(f"input size must be two multiples of {INPUT_SIZE_MULTIPLE_PX} in [{INPUT_SIZE_MULTIPLE_PX}, "
                          f"{MAX_INPUT_SIDE_PX}] px (W_in, H_in), got {tuple(input_size)}")
    input_size = (int(input_size[0]), int(input_size[1]))
    data_dir, out_path = Path(data_dir), Path(out_path)
    train_set = SignDataset(data_dir, "train", input_size, augment=True, seed=seed)
    if len(train_set) == 0:
        raise ConfigError(f"{data_dir / 'train.jsonl'} has no images; generate the dataset first")
    val_set = SignDataset(data_dir, "val", input_size) if (data_dir / "val.jsonl").is_file() else None
    if out_path.exists() and not (resume or overwrite):  # a finished checkpoint, or a file that is not one at all
        raise ConfigError(f"--out {out_path} already exists; pass --resume to continue training it, --overwrite to "
                          "replace it, or choose another --out")

    arch = {"width_mult": float(width_mult), "depth": int(depth), "num_classes": len(SIGN_CLASSES), "act": act}
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        model = build_detector(**arch)
    model.to(device)
    optimizer = torch.optim.AdamW(_param_groups(model, weight_decay), lr=lr, betas=(0.9, 0.999))
    ema = ModelEMA(model, ema_decay)
    steps_per_epoch = math.ceil(len(train_set) / batch_size)
    total_steps = epochs * steps_per_epoch
    warmup = warmup_steps if warmup_steps is not None else min(1000, max(1, total_steps // 10))
    meta: dict[str, Any] = {
        "arch": arch, "input_size": list(input_size), "class_names": list(SIGN_CLASSES), "seed": int(seed),
        "epochs": int(epochs), "batch_size": int(batch_size), "lr": float(lr), "weight_decay": float(weight_decay),
        "warmup_steps": int(warmup), "ema_decay": float(ema_decay), "train_images": len(train_set),
        "data_dir": str(data_dir), "torch_version": str(torch.__version__),
    }

    start_epoch, step, history = 0, 0, []
    if resume and out_path.is_file():
        checkpoint = load_checkpoint(out_path)
        _check_resumable(meta, checkpoint["meta"], out_path)
        state = checkpoint["train_state"]
        if not {"raw_model", "ema", "step", "history"} <= set(state) or checkpoint["optimizer"] is None:
            raise ConfigError(f"checkpoint {out_path} holds no training state to resume from; run without --resume")
        model.load_state_dict(state["raw_model"])
        ema.load_state_dict(state["ema"])
        optimizer.load_state_dict(checkpoint["optimizer"])
        start_epoch, step, history = int(checkpoint["epoch"]), int(state["step"]), list(state["history"])
        tqdm.write(f"resuming {out_path} after epoch {start_epoch}/{epochs} (step {step})")
        earlier, here = (history[-1].get("ran_on") if history else None), ran_on(device)  # older weights lack it
        if earlier is not None and earlier != here:
            tqdm.write(f"note: epoch {start_epoch} ran on {earlier}, the rest runs on {here}; the weights "
                       "will not equal an uninterrupted run's bit for bit")
    elif resume:
        tqdm.write(f"no checkpoint at {out_path}; starting from epoch 1")

    for epoch in range(start_epoch, epochs):
        started = time.perf_counter()
        model.train()
        train_set.set_epoch(epoch)
        order_gen = torch.Generator().manual_seed(_seed_for(seed, epoch))
        order = torch.randperm(len(train_set), generator=order_gen).tolist()
        loader = DataLoader(train_set, batch_size=batch_size, sampler=order, collate_fn=collate, num_workers=0,
                            generator=order_gen)
        sums = dict.fromkeys(LOSS_TERMS, 0.0)
        bar = tqdm(loader, desc=f"epoch {epoch + 1}/{epochs}", disable=not progress, leave=False, dynamic_ncols=True)
        for batch_index, (images, targets) in enumerate(bar, 1):
            lr_now = lr_at(step, total_steps, lr, warmup, min_lr_ratio)
            for group in optimizer.param_groups:
                group["lr"] = lr_now
            images = images.to(device)
            targets = [{k: v.to(device) for k, v in t.items()} for t in targets]
            losses = compute_loss(model(images), targets, weights=loss_weights)
            _check_finite(losses, epoch + 1, step + 1, lr_now)
            optimizer.zero_grad(set_to_none=True)
            losses["total"].backward()
            nn.utils.clip_grad_norm_(model.parameters(), grad_clip_norm)
            optimizer.step()
            ema.update(model)
            step += 1
            for name in LOSS_TERMS:
                sums[name] += float(losses[name].detach())
            means = {name: sums[name] / batch_index for name in LOSS_TERMS}
            bar.set_postfix({name: f"{v:.3f}" for name, v in means.items()}, refresh=False)
            if log_every and step % log_every == 0:
                tqdm.write(f"  step {step}/{total_steps} lr {lr_now:.2e} " + " ".join(f"{k} {v:.4f}" for k, v in means.items()))
        bar.close()

        record: dict[str, Any] = {"epoch": epoch + 1, **{k: sums[k] / steps_per_epoch for k in LOSS_TERMS}, "lr": lr_now}
        if val_set is not None and len(val_set):
            record["map50"] = evaluate_map50(ema.model, val_set, device=device)
            record["mAP50"] = mean_ap(record["map50"])
        record["seconds"] = time.perf_counter() - started
        record["ran_on"] = ran_on(device)
        history.append(record)
        tqdm.write(f"epoch {epoch + 1}/{epochs}: " + " ".join(f"{k} {record[k]:.4f}" for k in LOSS_TERMS)
                   + (f" val mAP50 {record['mAP50']:.3f} (" + ", ".join(f"{c} {ap:.3f}" for c, ap in record["map50"].items()) + ")"
                      if "map50" in record else "") + f" [{record['seconds']:.0f} s]")
        train_state = {"raw_model": model.state_dict(), "ema": ema.state_dict(), "step": step, "history": history}
        save_checkpoint(out_path, ema.model, optimizer, epoch + 1, {**meta, "history": history}, train_state)
    return {"out_path": str(out_path), "epochs": epochs, "history": history}


def run_from_args(args: argparse.Namespace) -> int:
    """Train as `avsim detector train`'s parsed `args` ask (device, data and an existing --out checked first);
    returns the exit status. Ctrl-C says where the last finished epoch is.
    """
    check_device(args.device)  # a device this torch build lacks is one line, before the data is read
    try:
        result = train(args.data, args.out, epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, seed=args.seed,
                       resume=args.resume, input_size=args.input_size or DEPLOY_INPUT_SIZE, log_every=args.log_every,
                       device=args.device, overwrite=args.overwrite, width_mult=args.width_mult, progress=not args.no_progress)
    except KeyboardInterrupt:
        kept = (f"the last finished epoch is in {args.out}; resume with the same command and --resume"
                if Path(args.out).is_file() else "no epoch had finished, so there is nothing to resume")
        raise Interrupted(kept) from None
    print(f"wrote {result['out_path']}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m avsim.perception.detector.train`: `avsim detector train` with its own error boundary."""
    prog = "python -m avsim.perception.detector.train"
    parser = OneLineArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_train_arguments(parser)
    args = parser.parse_args(argv)

    def command() -> int:
        check_declared_outputs(args)  # --out, before any work, as `avsim detector train` checks it
        return run_from_args(args)

    return run_guarded(command, prog=prog)


if __name__ == "__main__":
    raise SystemExit(main())
