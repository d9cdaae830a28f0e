"""The training command's flags, in a module without torch so `avsim --help` starts fast."""

from __future__ import annotations

import argparse

from avsim.outputs import FILE, add_output_argument
from avsim.validation import number_flag


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training flags, shared by `avsim detector train` and `python -m avsim.perception.detector.train`."""
    parser.add_argument("--data", required=True, help="dataset directory with train.jsonl (and val.jsonl)")
    add_output_argument(parser, "--out", kind=FILE, required=True, help="checkpoint / weights file, rewritten each epoch")
    parser.add_argument("--epochs", type=number_flag(1, 10_000, integer=True), default=6, help="total epochs (6 made the shipped weights)")
    parser.add_argument("--seed", type=number_flag(0, 2**32 - 1, integer=True), default=0)
    parser.add_argument("--resume", action="store_true", help="continue from --out if it holds a checkpoint")
    parser.add_argument("--batch-size", type=number_flag(1, 4096, integer=True), default=16)
    parser.add_argument("--lr", type=number_flag(0, 1, lo_open=True), default=2e-3, help="peak AdamW learning rate")
    parser.add_argument("--input-size", default=None, help="W_inxH_in, multiples of 32 (default: the deployed 640x480)")
    parser.add_argument("--width-mult", type=number_flag(0.125, 4), default=1.0,
                        help="channel width multiple of the deployed network (0.125 .. 4)")
    parser.add_argument("--log-every", type=number_flag(0, None, integer=True), default=50, help="steps between log lines (0: none)")
    parser.add_argument("--device", default="cpu", help="torch device: cpu (default), cuda, cuda:N or mps, if this torch build has it")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
