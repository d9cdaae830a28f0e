"""The training command's flags, in a module without torch so `avsim --help` starts fast."""

from __future__ import annotations

import argparse

from avsim.outputs import FILE, add_output_argument


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training flags, shared by `avsim detector train` and `python -m avsim.perception.detector.train`."""
    parser.add_argument("--data", required=True, help="dataset directory with train.jsonl (and val.jsonl)")
    add_output_argument(parser, "--out", kind=FILE, required=True, help="checkpoint / weights file, rewritten each epoch")
    parser.add_argument("--epochs", type=int, default=6, help="total epochs (6 made the shipped weights)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resume", action="store_true", help="continue from --out if it holds a checkpoint")
    parser.add_argument("--batch-size", type=int, default=16)
    parser.add_argument("--lr", type=float, default=2e-3, help="peak AdamW learning rate")
    parser.add_argument("--input-size", default=None, help="W_inxH_in, multiples of 32 (default: the deployed 640x480)")
    parser.add_argument("--width-mult", type=float, default=1.0)
    parser.add_argument("--log-every", type=int, default=50, help="steps between log lines (0: none)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
