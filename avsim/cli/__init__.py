"""The `avsim` command line, one module per command group (`avsim --help` lists the commands).

- `command`: the parser, assembled from the groups, and `main`, the error boundary;
- `run`, `batches` (reproduce, sweep, leaderboard), `snapshot`, `detect` (detect, replay),
  `bench`, `detector` and `attack`: each group's subcommands and what they do;
- `flags`, `overrides` (`--set KEY=VALUE`) and `recording_modes` (`--rrd`/`--mcap` of batches):
  what several groups share.

The modules import nothing of the simulator at the top, so `avsim --help` is fast and `main`
checks the renderer before MuJoCo is imported.
"""

from avsim.cli.command import build_parser, iter_parsers, main

__all__ = ["build_parser", "iter_parsers", "main"]
