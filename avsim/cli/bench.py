"""`avsim bench`: speed on this machine (physics, rendering, the closed loop), `--profile` where a
run's time goes, `--recording` what recording adds. Prints measured figures only."""

from __future__ import annotations

import argparse


def _cmd_bench(args: argparse.Namespace) -> int:
    from avsim.sensors.gl import check_offscreen_rendering

    check_offscreen_rendering()  # every printout renders: no EGL is one line before the first figure, not after it
    if args.profile:
        from avsim.bench.profile import run_profile

        run_profile(quick=args.quick)
        return 0
    if args.recording:
        from avsim.bench.recording_overhead import print_recording_overhead

        print_recording_overhead(repeats=1 if args.quick else 3)
        return 0
    from avsim.bench.speed import run_benchmarks

    run_benchmarks(quick=args.quick)
    return 0


def add_commands(sub) -> None:
    """Add `avsim bench` to the subcommands `sub`."""
    bench = sub.add_parser("bench", help="print physics, rendering and closed-loop speed on this machine")
    bench.add_argument("--quick", action="store_true", help="fewer repetitions")
    only = bench.add_mutually_exclusive_group()  # each prints one measurement instead of the whole bench
    only.add_argument("--profile", action="store_true",
                      help="where one run's and one batch's time goes, stage by stage, beside the speed targets")
    only.add_argument("--recording", action="store_true",
                      help="only what --rrd and --mcap add to a run: wall time and file size (docs/recording.md)")
    bench.set_defaults(func=_cmd_bench)
