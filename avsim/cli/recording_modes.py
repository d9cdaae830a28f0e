"""The batch commands' recording flags, `--rrd none|failed|all` and `--mcap none|failed|all`.

Apart from `avsim.experiments.recordings`, which applies them, because the command line must
not import the simulator before it has checked the renderer (`avsim.cli.command`).
"""

from __future__ import annotations

import argparse

# avsim.experiments.recordings.RECORD_MODES (a test holds them equal), not imported: it imports the simulator.
RECORD_CHOICES = ("none", "failed", "all")


def add_recording_modes(parser: argparse.ArgumentParser, prefix: str = "") -> None:
    """--rrd and --mcap: which of a batch's runs are recorded; `prefix` starts their help."""
    # dest *_mode: these name runs, not files (`avsim run --rrd FILE` is an output path).
    parser.add_argument("--rrd", dest="rrd_mode", default="failed", choices=RECORD_CHOICES,
                        help=f"{prefix}rerun recordings of no run, the runs whose car failed (ran the sign, a phantom "
                             "stop, a stop short of the braking gate; the default) or every run, under OUT/rrd/; any "
                             "run is recorded later by avsim run --config ... --cell ... --seed ... --rrd FILE "
                             "(docs/recording.md)")
    parser.add_argument("--mcap", dest="mcap_mode", default="none", choices=RECORD_CHOICES,
                        help=f"{prefix}ROS 2 bags (MCAP, needs avsim[ros]) of the same choice of runs, under OUT/mcap/ "
                             "(default none; docs/ros.md)")
