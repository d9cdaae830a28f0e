"""Recordings of a batch's runs on request: `--rrd none|failed|all` (and `--mcap`, the same rules).

    specs = with_recordings(specs, out_dir, rrd="failed", mcap="none")    # an iterator: each spec as it is drawn

none    no recordings;
failed  only the runs whose car failed (`avsim.experiments.failures`: ran the sign, stopped
        short of the braking gate, phantom stop, ...), the default for `--rrd`: what a
        researcher needs to inspect a surprise;
all     every run.

Under `failed` every run is recorded, to a temporary file, and the recording is kept only when
the car failed (`avsim.runner.run_recorded`'s `keep_if`); the others are deleted when their run
ends. The two flags may differ: `--rrd failed --mcap all` keeps a bag of every run and an .rrd of
the failed ones. Any other run is recorded afterwards, bit for bit, by
`avsim run --config FILE --cell CELL --seed K --rrd RUN.rrd` (docs/recording.md).

Files go to `<out>/rrd/<experiment>/<cell>__seed<K>.rrd` (`.mcap` under `<out>/mcap/`), the cell
as a file name (`slug`); the batch record's `rrd` and `mcap` keys name them, relative to `<out>`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from pathlib import Path

from avsim.errors import ConfigError
from avsim.experiments.run_task import RunSpec
from avsim.recording.ros_types import require_rosbags

RECORD_MODES = ("none", "failed", "all")
DEFAULT_RRD = "failed"
DEFAULT_MCAP = "none"
# Recording kind -> (folder under the batch folder, file suffix).
KINDS = {"rrd": ("rrd", ".rrd"), "mcap": ("mcap", ".mcap")}


def check_modes(rrd: str, mcap: str) -> None:
    """A one-line ConfigError for a mode not in RECORD_MODES, or bags asked for without the ros extra."""
    for flag, mode in (("--rrd", rrd), ("--mcap", mcap)):
        if mode not in RECORD_MODES:
            raise ConfigError(f"{flag} must be one of {', '.join(RECORD_MODES)}, got '{mode}'")
    if mcap != "none":
        require_rosbags()  # before the batch, not as an error in each of its runs


def recording_flags(rrd: str, mcap: str) -> str:
    """The flags that ask for these modes, for a manifest's command and a resume hint: "" at the defaults."""
    return "".join(f" {flag} {mode}" for flag, mode, default in (("--rrd", rrd, DEFAULT_RRD), ("--mcap", mcap, DEFAULT_MCAP))
                   if mode != default)


def recording_folders(experiments: Iterable[str], *, rrd: str, mcap: str) -> list[str]:
    """The folders, relative to the batch folder, that `with_recordings` puts the recordings of these
    experiments' runs in ("rrd/sweep_smoke"): for `locked_output` to check before the first run, since
    a recording is written only as its run ends."""
    return [f"{KINDS[kind][0]}/{experiment}" for kind, mode in (("rrd", rrd), ("mcap", mcap)) if mode != "none"
            for experiment in experiments]


def slug(name: str) -> str:
    """A cell name as a file name: "attacked sign, adjusted" -> "attacked_sign_adjusted"."""
    return "_".join("".join(c if c.isalnum() else " " for c in name.lower()).split())


def with_recordings(specs: Iterable[RunSpec], out_dir: str | Path, *, rrd: str = DEFAULT_RRD,
                    mcap: str = DEFAULT_MCAP) -> Iterator[RunSpec]:
    """`specs` with the recording paths and rule that `rrd` and `mcap` (RECORD_MODES) ask for,
    each as it is drawn (a plan stays lazy: `avsim.experiments.plan.Plan.then`). The modes are
    checked at the call (`check_modes`, which a command calls before it writes anything)."""
    check_modes(rrd, mcap)
    wanted = {kind: mode for kind, mode in (("rrd", rrd), ("mcap", mcap)) if mode != "none"}
    return _recorded(specs, Path(out_dir), wanted) if wanted else iter(specs)


def _recorded(specs: Iterable[RunSpec], out: Path, wanted: dict[str, str]) -> Iterator[RunSpec]:
    seen: dict[tuple[str, str], int] = {}
    for spec in specs:
        name = f"{slug(spec.cell)}__seed{spec.seed}"
        key = (spec.experiment, name)
        seen[key] = seen.get(key, 0) + 1
        if seen[key] > 1:  # two configs under one label (a leaderboard's): the config hash tells them apart
            name = f"{name}__{spec.spec_hash[:8]}"
        paths = {f"{kind}_path": str(out / KINDS[kind][0] / spec.experiment / f"{name}{KINDS[kind][1]}") for kind in wanted}
        whens = {f"{kind}_when": mode for kind, mode in wanted.items()}
        yield dataclasses.replace(spec, **paths, **whens)
