"""One run of a batch, found in the batch's results file, as the config that runs it again.

    config = config_from_results("results/sweep/results.jsonl", "scenario.speed_kmh=50", seed=3)

`avsim run --config RESULTS.jsonl --cell CELL --seed K` uses it, so a run of any batch (a
sweep's grid point, a leaderboard entry, an attack sweep's texture) can be run again, for
example to record it with `--rrd` or `--mcap`, without its batch file. Every record of a
finished run holds its resolved config (`result.config`); the config read back must hash to
the record's `spec_hash`, which also covers the sign texture's bytes, so a run is never
re-run on a config or a texture that has changed since. Experiment files (`experiments/*.toml`)
need no results file: `avsim run --config FILE.toml --cell CELL --seed K`.
"""

from __future__ import annotations

import os
from pathlib import Path

from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.experiments.results_file import read_records
from avsim.experiments.run_task import config_hash


def config_from_results(path: str | os.PathLike, cell: str | None, seed: int) -> SimConfig:
    """The resolved config of the record of (`cell`, `seed`) in the results file `path`.

    A one-line ConfigError when the file is missing or not avsim's, no record (or more than one
    config) matches, the run failed (it has no result), or the config or texture has changed.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"results file {path} does not exist; pass a batch's results.jsonl or runs.jsonl")
    records = read_records(path)
    if cell is None:
        raise ConfigError(f"--config {path} needs --cell: one of the file's cells, e.g. \"{records[0]['cell']}\""
                          if records else f"{path} holds no runs")
    matches = [r for r in records if r["cell"] == cell and r["seed"] == seed]
    if not matches:
        cells = sorted({r["cell"] for r in records})
        shown = ", ".join(f'"{c}"' for c in cells[:5]) + (", ..." if len(cells) > 5 else "")
        raise ConfigError(f"{path} has no run of cell \"{cell}\" at seed {seed}; its cells: {shown}")
    if len({r["spec_hash"] for r in matches}) > 1:
        experiments = ", ".join(sorted({r["experiment"] for r in matches}))
        raise ConfigError(f"{path} has {len(matches)} different runs of cell \"{cell}\" at seed {seed} (experiments "
                          f"{experiments}); run the experiment file instead: avsim run --config FILE.toml --cell ...")
    record = matches[0]
    if record["status"] != "ok":
        raise ConfigError(f"that run failed ({record['error']}), so its record holds no config; run it from its "
                          "experiment file to see the error again")
    config = with_overrides(SimConfig(), record["result"]["config"])
    if config_hash(config) != record["spec_hash"]:
        raise ConfigError(f"the run's config or its sign texture ({config.scenario.sign}) has changed since it ran "
                          f"(the hash differs from the record's); it cannot be run again bit for bit")
    return config
