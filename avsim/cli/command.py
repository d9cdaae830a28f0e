"""Command-line entry point: `avsim run`, `avsim detect`, `avsim snapshot`, `avsim sweep`, ... (`avsim --help`).

`main` is the one error boundary, and runs in this order for every subcommand:
1. the renderer MUJOCO_GL names was checked by `avsim.cli.main` before this module was imported
   (importing it loads MuJoCo, which fails at import on a bad MUJOCO_GL); it is checked again here, for
   callers of this `main`;
2. every output path the subcommand declared (`avsim.outputs.add_output_argument`) is checked,
   before any work starts;
3. the subcommand runs.
What the user sees when something stops it is one line on stderr (`avsim.boundary`, shared
with the `python -m avsim....` entry points): exit 2 for bad input, 128 + the signal for Ctrl-C
(130), SIGTERM (143) or SIGHUP (129), 1 for a full disk or a bug. `--debug` (anywhere on the
command line) prints the full traceback as well.

Each command group is a module of `avsim.cli` with an `add_commands(sub)`; a new group is one
module and one entry of `COMMAND_GROUPS`.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence

from avsim.boundary import run_guarded
from avsim.cli import attack, batches, bench, detect, detector, realism, run, snapshot
from avsim.config import check_seed
from avsim.library_output import quiet_opencv_logs, quiet_rust_logs, route_mujoco_warnings_to_log
from avsim.outputs import check_declared_outputs
from avsim.sensors.gl_backend import check_gl_backend
from avsim.validation import OneLineArgumentParser
from avsim.workers import quiet_resource_tracker

# One module per command group, each adding its subcommands in this order (`avsim --help` lists them so):
# run; reproduce, sweep, leaderboard; snapshot; detect, replay; bench; detector ...; attack ...
COMMAND_GROUPS = (run, batches, snapshot, detect, bench, detector, attack, realism)


def build_parser() -> argparse.ArgumentParser:
    """The `avsim` parser: every command group's subcommands, and `--debug` on each of them."""
    parser = OneLineArgumentParser(prog="avsim", description="Closed-loop stop-sign attack and defence simulator on MuJoCo.")
    sub = parser.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.add_commands(sub)
    parser.add_argument("--debug", action="store_true", help="on an error, print the full traceback too")
    for _, child in iter_parsers(parser):
        if child is not parser:
            # SUPPRESS: a subcommand without --debug must not reset the top-level flag.
            child.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return parser


def iter_parsers(parser: argparse.ArgumentParser, name: str = "avsim") -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every parser of the command line, subcommands included: ("avsim attack generate", parser), ..."""
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, child in action.choices.items():
                yield from iter_parsers(child, f"{name} {sub_name}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `avsim` command line; returns the exit status (see the module docstring)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # argparse printed its one line (or --help); its status, as for any refusal
        return exc.code if isinstance(exc.code, int) else 2

    def command() -> int:
        check_gl_backend()  # before anything imports MuJoCo, which fails at import on a bad MUJOCO_GL
        route_mujoco_warnings_to_log()  # its instability printout would precede the one-line PhysicsError
        quiet_rust_logs()  # rerun's own lines about a full disk would precede the one-line OutputError
        quiet_opencv_logs()  # and OpenCV's, once a frame, about an .mp4 a full disk cuts
        quiet_resource_tracker()  # a SIGKILLed batch leaves no multiprocessing warning on the terminal
        check_declared_outputs(args)  # before any work: a bad path never costs a finished run
        if getattr(args, "seed", None) is not None:  # every subcommand's --seed, one range
            check_seed(args.seed, "--seed")
        return args.func(args)

    return run_guarded(command, prog="avsim", debug=bool(getattr(args, "debug", False)))

