"""`avsim realism`: the render realism benchmark's command (`avsim.realism`, docs/realism.md).

`avsim.cli.command` adds it to its parser (`add_commands`) and is its error boundary: every name is
checked before anything renders, and the outputs are written whole or not at all.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from avsim.outputs import FOLDER, add_output_argument, refuse_earlier_outputs, temporary_path, write_text
from avsim.realism.frame_set import BIN_WIDTH_M, DEFAULT_MAX_DIST_M, MAX_DIST_LIMIT_M
from avsim.realism.settings import NETWORKS, SETTINGS
from avsim.validation import name_list_flag, number_flag

DEFAULT_SETTINGS = "baseline,photo"
DEFAULT_NETWORKS = "coco,yolo,detector"
# What a run writes into --out.
REALISM_OUTPUTS = ("report.md", "recall.png", "frames.jsonl")


_max_dist_range = number_flag(DEFAULT_MAX_DIST_M, MAX_DIST_LIMIT_M, integer=True, unit="m")


def _max_dist_flag(text: str) -> int:
    """`--max-dist-m`: an integer in range, on the 5-m bins' grid."""
    value = _max_dist_range(text)
    if value % BIN_WIDTH_M:
        raise argparse.ArgumentTypeError(f"must be a multiple of {BIN_WIDTH_M} m (the bins' width), got {text}")
    return value


def _cmd_realism(args: argparse.Namespace) -> int:
    from avsim.realism.benchmark import BenchmarkPlan, run_benchmark
    from avsim.cli.overrides import parse_set
    from avsim.experiments.set_overrides import set_flags
    from avsim.realism.report import report, write_figure
    from avsim.realism.set_values import REALISM_SET
    from avsim.software import software_versions
    from avsim.world.towns import TOWNS

    towns = args.towns or TOWNS.names()
    for town in towns:
        TOWNS.get(town)  # every name checked before anything renders
    out = Path(args.out)
    refuse_earlier_outputs(out, REALISM_OUTPUTS)
    settings = tuple(SETTINGS[name] for name in args.settings)
    overrides = parse_set(args.set)
    REALISM_SET.check(overrides, settings)
    plan = BenchmarkPlan(settings, tuple(towns), args.frames, tuple(args.networks), args.threshold, args.seed,
                         args.max_dist_m, overrides)
    rows = run_benchmark(plan, args.workers)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "frames.jsonl", "".join(json.dumps(row) + "\n" for row in rows))
    text = report(rows, args.threshold, software_versions(), set_flags(overrides))
    write_text(out / "report.md", text)
    figure = temporary_path(out / "recall.png", ".png")
    write_figure(rows, figure)
    os.replace(figure, out / "recall.png")
    print(text)
    print(f"wrote {out}/{', '.join(REALISM_OUTPUTS)}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """`avsim realism ...` on the command line's subcommands."""
    realism = sub.add_parser("realism", help="render realism benchmark: recall by distance, false stop signs and AP of "
                                             "the real detectors on a fixed set of renders, per render setting")
    realism.add_argument("--settings", type=name_list_flag(tuple(SETTINGS)), default=DEFAULT_SETTINGS.split(","),
                         help=f"comma-separated render settings compared side by side (default {DEFAULT_SETTINGS}; "
                              f"choose from {', '.join(SETTINGS)})")
    realism.add_argument("--networks", type=name_list_flag(tuple(NETWORKS)), default=DEFAULT_NETWORKS.split(","),
                         help=f"comma-separated networks (default {DEFAULT_NETWORKS})")
    realism.add_argument("--towns", type=name_list_flag(), help="comma-separated towns (default: every town)")
    realism.add_argument("--frames", type=number_flag(1, 1000, integer=True), default=2,
                         help="scene draws per town (default 2): each gives every camera one frame per 5-m bin from "
                              "10 m to --max-dist-m and 2 roadside views, with its own placement and daylight")
    realism.add_argument("--max-dist-m", type=_max_dist_flag, default=DEFAULT_MAX_DIST_M,
                         help=f"end of the farthest 5-m bin [m], a multiple of 5 from {DEFAULT_MAX_DIST_M} to "
                              f"{MAX_DIST_LIMIT_M} (default {DEFAULT_MAX_DIST_M}); the closed-loop files start the "
                              f"car 150 m out, and a false stop sign can open the braking gate beyond 60 m")
    realism.add_argument("--threshold", type=number_flag(0, 1, lo_open=True, hi_open=True), default=0.5,
                         help="confidence that counts (the braking threshold, default 0.5)")
    realism.add_argument("--seed", type=int, default=0, help="seed of the frame set (default 0)")
    realism.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="give every frame this camera.* or scenario.* value, e.g. --set camera.fovy_deg=40 "
                              "(repeatable); a key a scene draw or one of --settings sets is refused")
    realism.add_argument("--workers", type=number_flag(1, 64, integer=True), default=min(2, os.cpu_count() or 1),
                         help="worker processes (default 2)")
    add_output_argument(realism, "--out", kind=FOLDER, default="results/realism",
                        help="output folder for report.md, recall.png and frames.jsonl (default results/realism)")
    realism.set_defaults(func=_cmd_realism)
