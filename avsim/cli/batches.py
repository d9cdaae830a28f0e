"""The batch commands: `avsim reproduce` (the study's tables), `avsim sweep` (a grid of config
values) and `avsim leaderboard` (every defence against every attack), each run by a pool of
worker processes or by Ray."""

from __future__ import annotations

import argparse
from pathlib import Path

from avsim.cli.flags import BATCH_FLAG, SEEDS_FLAG, WORKERS_FLAG, add_set_flag, add_setting_flag
from avsim.cli.overrides import parse_set
from avsim.errors import ConfigError
from avsim.cli.recording_modes import add_recording_modes
from avsim.outputs import FOLDER, add_input_argument, add_output_argument
from avsim.realism.settings import SETTINGS
from avsim.workers import BATCH_HELP, DEFAULT_BATCH


def _recordings_written(out: Path, rrd_mode: str, mcap_mode: str) -> str:
    """"; recordings (--rrd failed) under OUT/rrd/", naming only the kinds asked for; "" for none. Each kind's
    folder is named as the kind, as `avsim.experiments.recordings.KINDS` names it (not imported: it imports the
    simulator; a test holds them equal)."""
    asked = [(f"--{kind} {mode}", f"{out}/{kind}/")
             for kind, mode in (("rrd", rrd_mode), ("mcap", mcap_mode)) if mode != "none"]
    if not asked:
        return ""
    return f"; recordings ({', '.join(flag for flag, _ in asked)}) under {' and '.join(folder for _, folder in asked)}"


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from avsim.experiments.reproduce import reproduce

    paths = [Path(p) for p in args.experiments] if args.experiments else None
    if args.resume is not None and args.out is not None:
        raise ConfigError("give --out (a new reproduction's parent folder) or --resume FOLDER (the one to finish), not both")
    out = reproduce(args.out or "results", resume=args.resume, quick=args.quick, seeds=args.seeds, workers=args.workers, experiment_paths=paths, progress=not args.no_progress,
                    backend=args.backend, address=args.address, batch=args.batch, everything=args.all, yes=args.yes,
                    rrd=args.rrd_mode, mcap=args.mcap_mode, setting=args.setting, overrides=parse_set(args.set),
                    cells=args.cells)
    print((out / "report.md").read_text())
    recordings = _recordings_written(out, args.rrd_mode, args.mcap_mode)
    print(f"wrote {out}/report.md, runs.jsonl and figures{recordings}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from avsim.experiments.render_setting import sweep_under_setting
    from avsim.experiments.sweep import load_sweep, run_sweep

    # Checks the size, then every grid value, before anything runs.
    sweep = sweep_under_setting(load_sweep(args.file, yes=args.yes, overrides=parse_set(args.set)), SETTINGS[args.setting])
    out = run_sweep(sweep, args.out, workers=args.workers, resume=args.resume, progress=not args.no_progress,
                    backend=args.backend, address=args.address, batch=args.batch, rrd=args.rrd_mode, mcap=args.mcap_mode)
    print((out / "summary.md").read_text())
    recordings = _recordings_written(out, args.rrd_mode, args.mcap_mode)
    print(f"wrote {out}/results.jsonl, summary.md and safety_map.png{recordings}")
    return 0


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    from avsim.experiments.leaderboard import DEFAULT_FILE, load_leaderboard
    from avsim.experiments.leaderboard_run import run_leaderboard
    from avsim.experiments.render_setting import board_under_setting

    # Checks the plan's size, then every run, before anything runs or is written.
    board = board_under_setting(load_leaderboard(args.file or DEFAULT_FILE, quick=args.quick, yes=args.yes,
                                                 overrides=parse_set(args.set)), SETTINGS[args.setting])
    out = run_leaderboard(board, args.out, quick=args.quick, workers=args.workers, resume=args.resume,
                          progress=not args.no_progress, backend=args.backend, address=args.address, batch=args.batch,
                          rrd=args.rrd_mode, mcap=args.mcap_mode)
    print((out / "leaderboard.md").read_text())
    recordings = _recordings_written(out, args.rrd_mode, args.mcap_mode)
    print(f"wrote {out}/leaderboard.md, leaderboard.png and results.jsonl{recordings}")
    return 0


BACKEND_HELP = "local: a pool of processes on this machine (default); ray: Ray tasks (pip install 'avsim[ray]')"


def _add_pool_flags(parser: argparse.ArgumentParser, workers_help: str, backend_help: str) -> None:
    """--workers, --backend, --batch and --address: where a batch command's runs run."""
    parser.add_argument("--workers", type=WORKERS_FLAG, help=workers_help)
    parser.add_argument("--backend", choices=("local", "ray"), default="local", help=backend_help)
    parser.add_argument("--batch", type=BATCH_FLAG, default=DEFAULT_BATCH, metavar="N", help=BATCH_HELP)
    parser.add_argument("--address", help="Ray cluster to run on, e.g. auto or HOST:6379 (with --backend ray)")


def add_commands(sub) -> None:
    """Add `avsim reproduce`, `avsim sweep` and `avsim leaderboard` to the subcommands `sub`."""
    rep = sub.add_parser("reproduce", help="run the study's tables and figures; writes results/<timestamp>/ with report.md")
    rep.add_argument("--quick", action="store_true", help="one seed per cell, for a smoke check")
    rep.add_argument("--seeds", type=SEEDS_FLAG, metavar="N",
                     help="seeds 0..N-1 for every cell instead of each file's own count (5 for the study's); a seed's "
                          "run is the same, bit for bit, whatever N is")
    rep.add_argument("--all", action="store_true",
                     help="also every other experiment file but the YOLOv3-tiny ones: the sensitivity, the COCO network's "
                          "closed loop and Table III, and the attack-success files (hours on 2 cores; the YOLO files "
                          "run by name with --experiments; the leaderboard is `avsim leaderboard`)")
    _add_pool_flags(rep, "runs at once: worker processes, or the local Ray cluster's CPUs (default: one per core); "
                         "with --address, at most this many in flight", BACKEND_HELP)
    add_output_argument(rep, "--out", kind=FOLDER, help="folder in which the timestamped results folder is made "
                                                         "(default: results)")
    add_output_argument(rep, "--resume", kind=FOLDER, metavar="FOLDER",
                        help="finish the reproduction in FOLDER (a results/<timestamp> folder): keep its ok runs, run "
                             "the rest with the same selection flags, then write the report")
    add_input_argument(rep, "--experiments", nargs="+", metavar="FILE",
                     help="experiment files to run instead of the study's (experiments/*.toml)")
    rep.add_argument("--cells", nargs="+", metavar="PATTERN",
                     help="run only the cells whose names match one of these shell-style patterns, quoted, e.g. "
                          "--cells 'Town03 *' (case counts; a file left with no cell is not run; each run is the "
                          "whole file's, bit for bit)")
    add_setting_flag(rep, "every run", "a file that sets one of its keys itself is refused")
    add_set_flag(rep, "every run", "a key on which a file's cells differ, or that its [vary] draws, is refused")
    rep.add_argument("--no-progress", action="store_true", help="no progress bar")
    rep.add_argument("--yes", action="store_true",
                     help="run more than 10,000 runs, add experiment files to a --resume folder, or resume one under "
                          "another --setting or --set (each refused without it)")
    add_recording_modes(rep)
    rep.set_defaults(func=_cmd_reproduce)

    swp = sub.add_parser("sweep", help="run every combination of a sweep file's grid; writes results.jsonl, summary.md "
                                       "and safety_map.png")
    add_input_argument(swp, "file", help="sweep file (experiments/sweeps/*.toml)")
    add_output_argument(swp, "--out", kind=FOLDER, required=True, help="results folder")
    _add_pool_flags(swp, "runs at once: worker processes, or the local Ray cluster's CPUs (default: one per core); "
                         "with --address, at most this many runs in flight (default: the cluster's CPUs)",
                    "local: a pool of processes on this machine (default); ray: Ray tasks, on a local "
                    "cluster or the one at --address (pip install 'avsim[ray]')")
    swp.add_argument("--resume", action="store_true",
                     help="keep the ok runs already in OUT/results.jsonl and run only the others")
    add_setting_flag(swp, "every run of the grid", "a file whose [defaults] or [grid] sets one of its keys is refused")
    add_set_flag(swp, "every run of the grid", "a [grid] key is refused")
    swp.add_argument("--no-progress", action="store_true", help="no progress bar")
    swp.add_argument("--yes", action="store_true", help="run a grid of more than 10,000 runs (refused without it)")
    add_recording_modes(swp)
    swp.set_defaults(func=_cmd_sweep)

    board = sub.add_parser("leaderboard", help="every defence against the attacks and on roads that need no stop; "
                                               "writes leaderboard.md, leaderboard.png and results.jsonl")
    add_input_argument(board, "file", nargs="?", help="leaderboard file (default experiments/leaderboards/defences.toml)")
    add_output_argument(board, "--out", kind=FOLDER, default="results/leaderboard", help="results folder")
    board.add_argument("--quick", action="store_true", help="the file's quick subset (quick_seeds per place and scenario)")
    _add_pool_flags(board, "runs at once: worker processes, or the local Ray cluster's CPUs (default: one per core)",
                    BACKEND_HELP)
    board.add_argument("--yes", action="store_true", help="run more than 10,000 runs (refused without it)")
    board.add_argument("--resume", action="store_true", help="keep the ok runs already in OUT/results.jsonl and run the rest")
    add_setting_flag(board, "every run of the board", "a file that sets one of its keys (in [defaults], [vary], a defence, "
                                                       "a condition or an availability scenario) is refused")
    add_set_flag(board, "every run of the board", "a key a defence, condition, place, availability scenario or [vary] "
                                                  "sets is refused")
    board.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_recording_modes(board)
    board.set_defaults(func=_cmd_leaderboard)
