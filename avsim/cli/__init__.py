"""The `avsim` command line, one module per command group (`avsim --help` lists the commands).

- `command`: the parser, assembled from the groups, and the error boundary every subcommand runs in;
- `run`, `batches` (reproduce, sweep, leaderboard), `snapshot`, `detect` (detect, replay),
  `bench`, `detector` and `attack`: each group's subcommands and what they do;
- `flags`, `overrides` (`--set KEY=VALUE`) and `recording_modes` (`--rrd`/`--mcap` of batches):
  what several groups share.

`main` (the `avsim` script and `python -m avsim`) checks the renderer MUJOCO_GL names
(`avsim.sensors.gl_backend`) before it imports the command modules. MuJoCo reads MUJOCO_GL when it
is first imported and fails there, with a traceback, on a value it does not know; the command
modules' imports reach MuJoCo (the config's key owners import the policies, which import the
perception interface), so the check has to come first.
"""

from __future__ import annotations

from collections.abc import Sequence

from avsim.boundary import run_guarded
from avsim.sensors.gl_backend import check_gl_backend

__all__ = ["main"]


def _check_renderer() -> None:
    check_gl_backend()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `avsim` command line; returns the exit status (`avsim.cli.command`)."""
    status = run_guarded(_check_renderer, prog="avsim")
    if status:
        return status
    # Imported only now: this import is what first loads MuJoCo (see the module docstring).
    from avsim.cli.command import main as command_line

    return command_line(argv)
