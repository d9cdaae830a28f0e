"""How many runs a plan (a sweep's grid x seeds, a reproduction's cells x seeds) may have.

The size is computed from the file's lists before a single run is built: a grid that
expands to millions of runs would otherwise spend minutes, and gigabytes, building configs
before any check or output. Past `RUNS_WITHOUT_YES` a command asks for `--yes`; past
`MAX_RUNS` it refuses (split the plan into several files).
"""

from __future__ import annotations

from avsim.errors import ConfigError

# About a day of closed-loop runs on a 2-core machine (a few seconds each); above it, a typo
# in a grid or a seed count is likelier than intent, so the user confirms with --yes.
RUNS_WITHOUT_YES = 10_000
# Each run's record is held in memory until the report (the run specs are not: `avsim.experiments.plan`):
# a million is a few GB.
MAX_RUNS = 1_000_000


def check_plan_size(runs: int, what: str, *, yes: bool) -> None:
    """A one-line ConfigError when `runs` is too many (see the module docstring); what: e.g.
    "sweep.toml: 40 grid points x 500 seeds"."""
    if runs > MAX_RUNS:
        raise ConfigError(f"{what} is {runs:,} runs, more than one command runs ({MAX_RUNS:,}); split it into "
                          f"several files, or use fewer values or seeds")
    if runs > RUNS_WITHOUT_YES and not yes:
        raise ConfigError(f"{what} is {runs:,} runs (over {RUNS_WITHOUT_YES:,}); pass --yes to run them all, or "
                          f"use fewer values or seeds")
