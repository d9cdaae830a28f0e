"""`avsim snapshot`: the front and side cameras' images at a distance from the stop line, or the
towns' front cameras side by side."""

from __future__ import annotations

import argparse

from avsim.cli.flags import add_scenario_flags, config_from_args, flag_overrides
from avsim.config_owners import check_snapshot_reads
from avsim.errors import ConfigError
from avsim.outputs import PREFIX, add_output_argument
from avsim.validation import name_list_flag, number_flag


def _cmd_snapshot(args: argparse.Namespace) -> int:
    from avsim.snapshot import check_snapshot_distance, save_snapshot, save_town_strip
    from avsim.world.towns import TOWNS

    config = config_from_args(args)
    check_snapshot_reads(config, flag_overrides(args), towns=args.towns is not None)  # a key set that no picture shows
    check_snapshot_distance(args.dist_m)
    if args.towns is None:
        if args.strip:
            raise ConfigError("--strip needs --towns (e.g. --towns town07,town03,town10): it puts their front cameras side by side")
        paths = save_snapshot(config, args.dist_m, args.out)
    else:
        towns = args.towns  # a non-empty list of names (name_list_flag)
        for town in towns:
            TOWNS.get(town)  # every name checked before anything renders
        if not args.strip:
            raise ConfigError("--towns goes with --strip (one picture of the towns' front cameras side by side); "
                              "for one town's cameras use --town")
        paths = [save_town_strip(config, towns, args.dist_m, args.out)]
    for path in paths:
        print(f"wrote {path}")
    return 0


def add_commands(sub) -> None:
    """Add `avsim snapshot` to the subcommands `sub`."""
    snap = sub.add_parser("snapshot", help="save front and side camera images at a distance from the stop line")
    add_scenario_flags(snap)
    snap.add_argument("--dist-m", type=number_flag(unit="m"), default=30.0, help="front bumper to stop line [m]")
    snap.add_argument("--towns", type=name_list_flag(), help="with --strip: comma-separated towns whose front cameras are put side by side")
    snap.add_argument("--strip", action="store_true",
                      help="write PREFIX.png: the front camera of each of --towns, side by side at half size")
    add_output_argument(snap, "--out", kind=PREFIX, suffixes=("_front.png", "_side.png", ".png"), default="snapshot",
                        help="output prefix; writes PREFIX_front.png and PREFIX_side.png (PREFIX.png with --strip)")
    snap.set_defaults(func=_cmd_snapshot)
