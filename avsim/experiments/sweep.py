"""Sweep files (`experiments/sweeps/*.toml`): every combination of a grid of config values, run.

    title = "Safety map: speed x attack budget x policy"
    seeds = 1                            # each grid point runs at scenario.seed = 0 .. seeds-1 (default 1)
    [defaults]                           # applied to every run: nested overrides, as in experiment files
    scenario = { town = "town07", placement = "standard" }
    [grid]                               # dotted config key -> the values it takes
    "scenario.speed_kmh" = [30, 60, 85]
    "scenario.sign" = ["clean", "yang"]
    "policy.name" = ["baseline", "side_camera"]

The runs are the cartesian product of the grid's lists, times the seeds, in a fixed order:
the grid keys in file order, the first key varying slowest and the seed fastest. A grid
key may also be written as a TOML dotted key (`scenario.speed_kmh = [...]`).

Everything is checked when the file is loaded, before any run starts: unknown top-level
and config keys, empty lists, repeated values, wrong types and out-of-range values (by the
config dataclasses), registry names (town, placement, policy, perception), sign textures
(each decoded as the scene decodes it; two names of one file, such as "clean" and
"stop_sign", are refused), and then every combination's full config (for limits that tie
two keys together). A policy or perception key of `[defaults]` or of a grid axis that no run
reads is refused, and so is a grid whose points differ only in keys their runs do not read
(`policy.vote_k` beside a `baseline` run): it would run one run twice (`avsim.config_owners`).
Each error is one `ConfigError` line naming the file, the place in it and the key.

`run_sweep` runs the specs through `avsim.experiments.batch.run_batch`, on its local pool of
processes or (backend "ray") as Ray tasks on a cluster; the records are the same either way.
Each run's config is built only when the batch draws on it (`Sweep.plan`, `avsim.experiments.plan`).
It writes into one folder:
    sweep.toml        the sweep file as it was run
    results.jsonl     one record per run (`avsim.experiments.run_task`), plus `point`: the run's
                      grid values, dotted key -> value; in grid order once the sweep is over
    manifest.json     command, backend, workers, wall time, runs, failures, versions
    summary.md        the safety map and every run's outcome (`avsim.experiments.sweep_report`)
    set.json          the --set values every run was given, when there were any (`avsim.experiments.set_overrides`)
    safety_map.png    the figure

With `resume`, runs whose config hash already has an `ok` record in results.jsonl are not
run again; failed runs are. A results.jsonl that is not avsim's, or has a corrupt line, is
refused before anything runs (`avsim.experiments.results_file.read_records`). Ctrl-C ends
the sweep with `Interrupted`, naming the finished runs and the command that resumes it. The hash is the run's whole config, so growing the grid (a new
speed) reuses every finished run. A sweep killed at any moment (even mid-write: a torn last
line is dropped before new records are appended) resumes to the same results.jsonl as a run
never stopped, `wall_s` aside.
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
import os
import shutil
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.config import SimConfig, with_overrides
from avsim.config_owners import check_read_by_some, dotted_keys, identical_runs, set_keys
from avsim.errors import ConfigError, RunsFailedError
from avsim.workers import DEFAULT_BATCH
from avsim.experiments.batch import check_backend, resolve_workers
from avsim.experiments.ray_backend import cluster_nodes
from avsim.software import software_versions
from avsim.experiments.output_lock import locked_output
from avsim.experiments.plan_size import check_plan_size
from avsim.experiments.recordings import (DEFAULT_MCAP, DEFAULT_RRD, check_modes, recording_flags, recording_folders,
                                          with_recordings)
from avsim.experiments.resumable import RESULTS_FILE, existing_records, manifest_history, run_resumable
from avsim.experiments.plan import Plan
from avsim.experiments.folder_setting import SETTING_FILE
from avsim.experiments.folder_terms import SWEEP_COPY, check_made_by, check_resumed_plan, check_resumed_terms, record_terms
from avsim.experiments.set_overrides import SET_FILE, checked_set, flags_of_items, flat_items, refuse_layered, set_title
from avsim.experiments.run_task import RunSpec
from avsim.experiments.sweep_report import FIGURE_FILE
from avsim.experiments.spec import as_table, check_networks, check_renderer, check_run_names, deep_merge, located, nested, read_run_file, reject_seed
from avsim.metrics import write_json_atomic
from avsim.realism.settings import BASELINE

TOP_LEVEL_KEYS = ("title", "seeds", "defaults", "grid")
DEFAULT_SEEDS = 1
SIGN_KEY = "scenario.sign"

Scalar = str | int | float | bool
# Every file a sweep writes into its folder (the module docstring), checked before the first run: the report is
# written only after the last one.
FOLDER_FILES = (SWEEP_COPY, RESULTS_FILE, "manifest.json", "summary.md", FIGURE_FILE, SET_FILE, SETTING_FILE)


@dataclass(frozen=True)
class SweepRun:
    """One run of a sweep: a grid point at one seed, with its final config.

    point: the grid's dotted keys -> this run's values (as the config holds them: 30 -> 30.0).
    """

    point: dict[str, Scalar]
    seed: int
    config: SimConfig

    @property
    def label(self) -> str:
        """The point as one line, e.g. "scenario.speed_kmh=30.0, policy.name=baseline"."""
        return point_label(self.point)


@dataclass(frozen=True)
class Sweep:
    """A loaded sweep file.

    base: SimConfig() with [defaults] applied; grid: (dotted key, values) in file order.
    """

    path: Path
    title: str
    seeds: int
    base: SimConfig
    grid: tuple[tuple[str, tuple[Scalar, ...]], ...]
    defaults_keys: frozenset[str] = frozenset()  # the dotted keys the file's [defaults] sets
    setting: str = BASELINE  # the render setting it runs under (`avsim sweep --setting`)
    set_items: tuple[tuple[str, Any], ...] = ()  # the --set values in its base config: (dotted key, value), sorted

    def layers(self) -> list[tuple[str, frozenset[str]]]:
        """Where the file and its --set values set keys (where, dotted keys): none of them may a --setting set too."""
        return [("[defaults]", self.defaults_keys), ("[grid]", frozenset(key for key, _ in self.grid)),
                ("--set", frozenset(key for key, _ in self.set_items))]

    @property
    def name(self) -> str:
        """The sweep file's stem (e.g. "speed_sweep")."""
        return self.path.stem

    @property
    def size(self) -> int:
        """The number of runs: grid points x seeds, computed without building any."""
        return math.prod(len(values) for _, values in self.grid) * self.seeds

    def points(self) -> list[dict[str, Scalar]]:
        """Every combination of grid values; the first key varies slowest."""
        return list(self.iter_points())

    def iter_points(self) -> Iterator[dict[str, Scalar]]:
        """`points`, one at a time."""
        keys = [key for key, _ in self.grid]
        for values in itertools.product(*(values for _, values in self.grid)):
            yield dict(zip(keys, values))

    def config_at(self, point: Mapping[str, Scalar], seed: int) -> SimConfig:
        """The config of one run: the sweep's base with the grid point's values and scenario.seed = `seed`."""
        overrides: dict[str, Any] = {"scenario": {"seed": seed}}
        for key, value in point.items():
            overrides = deep_merge(overrides, nested(key, value))
        return with_overrides(self.base, overrides)

    def runs(self) -> list[SweepRun]:
        """Every grid point at seeds 0 .. seeds-1, point by point."""
        return list(self.iter_runs())

    def iter_runs(self) -> Iterator[SweepRun]:
        """`runs`, one at a time: each config is built when it is asked for."""
        for point in self.iter_points():
            for seed in range(self.seeds):
                yield SweepRun(point, seed, self.config_at(point, seed))

    def spec_of(self, run: SweepRun) -> RunSpec:
        """A run as a batch spec: experiment = the sweep's name, cell = the point's label; no recording."""
        return RunSpec(self.name, run.label, run.seed, run.config)

    def specs(self) -> list[RunSpec]:
        """Every run as a batch spec (`spec_of`)."""
        return list(self.iter_specs())

    def iter_specs(self) -> Iterator[RunSpec]:
        """`specs`, one at a time."""
        return (self.spec_of(run) for run in self.iter_runs())

    def plan(self) -> Plan:
        """Every run as a batch spec, built only as a batch draws on it (`avsim.experiments.plan`)."""
        return Plan(self.size, self.iter_specs)


def point_label(point: Mapping[str, Scalar]) -> str:
    """A grid point as "key=value, key=value", in the grid's key order."""
    return ", ".join(f"{key}={value}" for key, value in point.items())


# ---- loading ---------------------------------------------------------------------------------

def load_sweep(path: str | os.PathLike, *, yes: bool = False, overrides: Mapping[str, Any] | None = None) -> Sweep:
    """Read and check a sweep file; see the module docstring for its format.

    yes: allow more than `plan_size.RUNS_WITHOUT_YES` runs (the user's --yes); the size is
    checked before any combination is built. overrides: `--set` values (nested), over [defaults] in every
    run; one a [grid] key sets is refused (`avsim.experiments.set_overrides`)."""
    path = Path(path)
    overrides = overrides or {}
    keys_given = checked_set(overrides)
    raw, title, seeds = read_run_file(path, "sweep", TOP_LEVEL_KEYS, DEFAULT_SEEDS)

    with located(path, "[defaults]"):
        defaults = as_table(raw.get("defaults", {}), "defaults")
        reject_seed(defaults)
        base = with_overrides(SimConfig(), defaults)
        check_run_names(base)
    with located(path, "--set"):
        base = with_overrides(base, overrides)
        check_run_names(base)
    with located(path, "[grid]"):
        grid = _parse_grid(raw.get("grid"), base)
    refuse_layered(path, keys_given, [("its [grid]", frozenset(key for key, _ in grid))])
    sweep = Sweep(path=path, title=set_title(title, overrides) if overrides else title, seeds=seeds, base=base,
                  grid=grid, defaults_keys=dotted_keys(defaults), set_items=tuple(flat_items(overrides).items()))
    check_plan_size(sweep.size, f"{path}: {sweep.size // seeds:,} grid points x {seeds:,} seeds", yes=yes)
    # Each value is valid alone; check every combination too (limits that tie two keys together).
    configs = []
    for point in sweep.iter_points():
        with located(path, f"[grid] point {point_label(point)}"):
            configs.append((point_label(point), sweep.config_at(point, 0)))
    _check_keys_read(path, defaults, sweep.grid, configs, keys_given)
    return sweep


def _check_keys_read(path: Path, defaults: Mapping[str, Any], grid: tuple[tuple[str, tuple[Scalar, ...]], ...],
                     configs: list[tuple[str, SimConfig]], keys_given: frozenset[str]) -> None:
    """Every policy and perception key of [defaults], every --set key (`keys_given`) and every grid axis is
    read by some run of the grid, and no two grid points make the same run (`avsim.config_owners`)."""
    for where, keys in (("[defaults]", set_keys(defaults)), ("--set", keys_given), ("[grid]", {key for key, _ in grid})):
        with located(path, where):
            check_read_by_some((config for _, config in configs), keys, runs="run of the grid")
    same = identical_runs(configs)
    if same is not None:
        first, second, differ = same
        raise ConfigError(f"{path}: [grid] points {first} and {second} are the same run: {', '.join(differ)} "
                          f"{'is' if len(differ) == 1 else 'are'} not read by its policy and perception, so the sweep would run "
                          "it twice under two labels; give the policy or perception that reads it a sweep file of its own")


def _parse_grid(raw: Any, base: SimConfig) -> tuple[tuple[str, tuple[Scalar, ...]], ...]:
    if raw is None:
        raise ConfigError("no [grid] table; add one of dotted config keys and value lists, e.g. \"scenario.speed_kmh\" = [30, 60]")
    entries = list(_flatten(as_table(raw, "grid")))
    if not entries:
        raise ConfigError("the grid is empty; give it at least one key, e.g. \"scenario.speed_kmh\" = [30, 60]")
    grid: list[tuple[str, tuple[Scalar, ...]]] = []
    for key, values in entries:
        if any(key == seen for seen, _ in grid):
            raise ConfigError(f"'{key}' is given twice")
        if key == "scenario.seed":
            raise ConfigError("'scenario.seed' cannot be a grid key: it is the run's seed, set by the top-level 'seeds'")
        if not isinstance(values, list):
            raise ConfigError(f"'{key}' must be a list of values, e.g. [30, 60], got {values!r}")
        if not values:
            raise ConfigError(f"'{key}' is an empty list; give it at least one value")
        checked: list[Scalar] = []
        loads: dict[Path, Scalar] = {}  # sign texture file -> the value that names it
        for value in values:
            if isinstance(value, (Mapping, list)):
                raise ConfigError(f"'{key}' values must be numbers, strings or booleans, got {value!r}")
            config = with_overrides(base, nested(key, value))  # unknown key, wrong type, out of range
            texture = check_run_names(config)
            check_networks(config)
            check_renderer(config)
            held = _lookup(config, key)
            if held in checked:
                raise ConfigError(f"'{key}' lists the value {value!r} twice")
            # Two names of one texture ("clean" and "stop_sign") would run the same run twice
            # under two labels; refused rather than merged, so the grid stays as written.
            if key == SIGN_KEY and texture in loads:
                raise ConfigError(f"'{key}' lists {loads[texture]!r} and {value!r}, which load the same texture "
                                  f"{texture}; list it once")
            loads[texture] = value
            checked.append(held)
        grid.append((key, tuple(checked)))
    return tuple(grid)


def _flatten(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """("scenario", {"speed_kmh": [..]}) and ("scenario.speed_kmh", [..]) both -> "scenario.speed_kmh"."""
    for key, value in table.items():
        if isinstance(value, Mapping):
            yield from _flatten(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}", value


def _lookup(config: SimConfig, dotted: str) -> Scalar:
    node: Any = config
    for part in dotted.split("."):
        node = getattr(node, part)
    return node


# ---- running ---------------------------------------------------------------------------------

def run_sweep(sweep: Sweep, out_dir: str | os.PathLike, *, workers: int | None = None, resume: bool = False,
              progress: bool = True, backend: str = "local", address: str | None = None,
              batch: int = DEFAULT_BATCH, rrd: str = DEFAULT_RRD, mcap: str = DEFAULT_MCAP) -> Path:
    """Run every point of `sweep` into `out_dir` (see the module docstring); returns `out_dir`.

    rrd, mcap: which runs are recorded, under OUT/rrd/ and OUT/mcap/ (`avsim.experiments.recordings`).

    workers: runs at once (default: one per core; on a Ray cluster at `address`, the cluster's
    CPUs). backend, address, batch: see `avsim.experiments.batch.run_batch`.
    Raises ConfigError, writing nothing, when `out_dir` already holds results and `resume` is
    off, the backend cannot run (Ray not installed), or another command holds `out_dir`.
    """
    check_backend(backend, address)
    check_renderer(sweep.base)  # a --setting's keys are in the base config, set after loading checked every point
    check_modes(rrd, mcap)
    out = Path(out_dir)
    workers = resolve_workers(workers, address)
    check_made_by(out, "avsim sweep")
    if resume:
        check_resumed_terms(out, sweep, "avsim sweep")
    # One command at a time in `out`; a folder made here and left without a record is removed.
    with locked_output(out, f"avsim sweep {sweep.path} --out {out}", results_name=RESULTS_FILE, files=FOLDER_FILES,
                       folders=recording_folders([sweep.name], rrd=rrd, mcap=mcap)):
        return _run_sweep_locked(sweep, out, workers=workers, resume=resume, progress=progress, backend=backend,
                                 address=address, batch=batch, rrd=rrd, mcap=mcap)


def _run_sweep_locked(sweep: Sweep, out: Path, *, workers: int | None, resume: bool, progress: bool, backend: str,
                      address: str | None, batch: int, rrd: str, mcap: str) -> Path:
    from avsim.experiments.sweep_report import write_sweep_report

    results_path = out / RESULTS_FILE
    existing = existing_records(results_path, resume)
    check_resumed_plan(out, existing, sweep.path, sweep.name, SWEEP_COPY)
    # The runs are built as the batch draws on them, never all at once (the plan's size and its
    # points' configs were checked when it was loaded); a record finds its grid point by its cell label.
    plan = sweep.plan().then(lambda specs: with_recordings(specs, out, rrd=rrd, mcap=mcap))
    point_of = {point_label(point): point for point in sweep.iter_points()}

    started = time.perf_counter()
    started_at = dt.datetime.now().astimezone()
    history = manifest_history(out / "manifest.json") if resume else []
    out.mkdir(parents=True, exist_ok=True)
    if sweep.path.resolve() != (out / SWEEP_COPY).resolve():
        shutil.copy2(sweep.path, out / SWEEP_COPY)
    record_terms(out, sweep)
    # The file ends in grid order, the same every time; records of runs no longer in the grid stay, after them.
    # --setting and --set, which the resume command and the manifest's command repeat.
    file_flags = f" --setting {sweep.setting}" if sweep.setting != BASELINE else ""
    file_flags += f" {flags_of_items(dict(sweep.set_items))}" if sweep.set_items else ""
    nodes = cluster_nodes(backend, address)
    records, ran = run_resumable(plan, results_path, existing,
                                 resume_command=f"avsim sweep {sweep.path} --out {out}{file_flags}{recording_flags(rrd, mcap)} --resume",
                                 workers=workers, progress=progress, description=sweep.name, backend=backend,
                                 address=address, decorate=lambda record: with_point(record, point_of[record["cell"]]),
                                 batch=batch)
    wall_s = time.perf_counter() - started
    options = [f"--workers {workers}" if workers is not None else "", f"--batch {batch}" if batch != DEFAULT_BATCH else "",
               f"--backend {backend}" if backend != "local" else "",
               f"--address {address}" if address is not None else "", file_flags.strip(), recording_flags(rrd, mcap).strip(),
               "--resume" if resume else ""]
    manifest = {
        "command": " ".join([f"avsim sweep {sweep.path} --out {out}", *filter(None, options)]),
        "started_at": started_at.isoformat(timespec="seconds"),
        "title": sweep.title,
        "wall_s": round(wall_s, 1),
        "backend": backend,
        "address": address,
        "workers": workers,
        "runs": len(records),
        "ran": ran,
        "reused": len(records) - ran,
        "failed": sum(1 for r in records if r["status"] == "failed"),
        "grid": {key: list(values) for key, values in sweep.grid},
        "seeds": sweep.seeds,
        "versions": software_versions(),
        "cluster_nodes": nodes,
        "history": history,
    }
    write_json_atomic(out / "manifest.json", manifest)
    write_sweep_report(out, sweep, records, manifest)
    if records and manifest["failed"] == len(records):
        first = next(r["error"] for r in records if r["status"] == "failed")
        raise RunsFailedError(f"every one of the {len(records)} runs failed (the first: {first}); "
                              f"see {out / 'summary.md'}")
    return out


def with_point(record: dict[str, Any], point: Mapping[str, Scalar]) -> dict[str, Any]:
    """`record` with its grid point after `seed`, so the file reads where-from first."""
    keys = list(record)
    cut = keys.index("seed") + 1 if "seed" in keys else len(keys)
    return {**{k: record[k] for k in keys[:cut]}, "point": dict(point), **{k: record[k] for k in keys[cut:]}}
