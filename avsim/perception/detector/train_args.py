"""The training command's flags, in a module without torch so `avsim --help` starts fast."""

from __future__ import annotations

import argparse

from avsim.outputs import FILE, add_output_argument
from avsim.validation import number_flag


# The backbone halves the image five times (its deepest map, C5, is at stride 32), so each side of the
# network's input is a multiple of 32. 4096 px is above any camera avsim renders (640x480 deployed),
# and a batch of 16 at that size already needs about 3 GB for the images alone.
INPUT_SIZE_MULTIPLE_PX = 32
MAX_INPUT_SIDE_PX = 4096


def input_size_flag(text: str) -> tuple[int, int]:
    """argparse `type` of --input-size: "WxH" -> (W_in, H_in), each a multiple of 32 in [32, 4096] px."""
    width, sep, height = text.strip().lower().partition("x")
    if not sep or not width.isdigit() or not height.isdigit():
        raise argparse.ArgumentTypeError(f"expects WxH, e.g. 640x480, got '{text}'")
    size = (int(width), int(height))
    if any(v % INPUT_SIZE_MULTIPLE_PX or not INPUT_SIZE_MULTIPLE_PX <= v <= MAX_INPUT_SIDE_PX for v in size):
        raise argparse.ArgumentTypeError(f"each side must be a multiple of {INPUT_SIZE_MULTIPLE_PX} in "
                                         f"[{INPUT_SIZE_MULTIPLE_PX}, {MAX_INPUT_SIDE_PX}] px, got '{text}'")
    return size


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training flags, shared by `avsim detector train` and `python -m avsim.perception.detector.train`."""
    parser.add_argument("--data", required=True, help="dataset directory with train.jsonl (and val.jsonl)")
    add_output_argument(parser, "--out", kind=FILE, required=True, help="checkpoint / weights file, rewritten each epoch")
    parser.add_argument("--epochs", type=number_flag(1, 10_000, integer=True), default=6, help="total epochs (6 made the shipped weights)")
    parser.add_argument("--seed", type=number_flag(0, 2**32 - 1, integer=True), default=0)
    existing = parser.add_mutually_exclusive_group()  # an existing --out is refused unless one of these says what to do
    existing.add_argument("--resume", action="store_true", help="continue from --out if it holds a checkpoint")
    existing.add_argument("--overwrite", action="store_true", help="replace an existing --out and start afresh")
    parser.add_argument("--batch-size", type=number_flag(1, 4096, integer=True), default=16)
    parser.add_argument("--lr", type=number_flag(0, 1, lo_open=True), default=2e-3, help="peak AdamW learning rate")
    parser.add_argument("--input-size", type=input_size_flag, default=None,
                        help="W_inxH_in, multiples of 32 up to 4096 (default: the deployed 640x480)")
    parser.add_argument("--width-mult", type=number_flag(0.125, 4), default=1.0,
                        help="channel width multiple of the deployed network (0.125 .. 4)")
    parser.add_argument("--log-every", type=number_flag(0, None, integer=True), default=50, help="steps between log lines (0: none)")
    parser.add_argument("--device", default="cpu", help="torch device: cpu (default), cuda, cuda:N or mps, if this torch build has it")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
