"""`avsim reproduce`: every table and figure of the study, run, recorded and reported.

    out = reproduce("results", quick=False, workers=2)

writes `results/<timestamp>/`:
    runs.jsonl            one record per run (see `avsim.experiments.run_task`), sorted by
                          experiment, cell and seed once the batch is over
    rrd/<experiment>/     rerun recordings of the runs `rrd` asks for (default: the failed ones,
                          `avsim.experiments.recordings`; `rerun FILE.rrd` opens one)
    mcap/<experiment>/    ROS 2 bags of the runs `mcap` asks for (default none)
    experiments/          the experiment files as they were run
    set.json              the --set values every run was given, when there were any
                          (`avsim.experiments.set_overrides`), for a resume to check
    cells.json            the --cells patterns, when some cells were chosen
                          (`avsim.experiments.cell_selection`), for a resume to check
    manifest.json         command, versions, workers, wall time, failures
    report.md, *.png      the study's tables beside ours, and the figures

Every experiment file is loaded and checked before anything is written, so a bad file
fails in one line with no half-made results folder.

A reproduction stopped part-way (Ctrl-C, a kill, a full disk, a crash) is finished with the same
command and `--resume FOLDER` (`reproduce(..., resume=FOLDER)`): the runs with an ok record in
FOLDER/runs.jsonl are kept, the others run, and the report is written over all of them. A run is
matched by experiment, cell, seed and config hash, so a run whose experiment file changed since
runs again; runs no longer asked for keep their records, after the others.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import os
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from avsim.errors import ConfigError, RunsFailedError
from avsim.workers import DEFAULT_BATCH
from avsim.experiments.batch import check_backend, resolve_workers
from avsim.experiments.cell_selection import CELLS_FILE, cell_flags, check_resumed_cells, record_cells, select_cells
from avsim.experiments.ray_backend import cluster_nodes
from avsim.software import software_versions
from avsim.experiments.figures import FIGURE_FILES
from avsim.experiments.folder_terms import REPRODUCE_RUNS
from avsim.experiments.recordings import (DEFAULT_MCAP, DEFAULT_RRD, check_modes, recording_flags, recording_folders,
                                          with_recordings)
from avsim.experiments.results_file import read_records
from avsim.experiments.resumable import manifest_history, run_resumable
from avsim.experiments.run_task import RunSpec
from avsim.experiments.output_lock import locked_output
from avsim.experiments.plan import Plan
from avsim.experiments.plan_size import check_plan_size
from avsim.experiments.render_setting import under_setting
from avsim.experiments.set_overrides import SET_FILE, check_resumed_set, experiment_with_set, flat_items, record_set, set_flags
from avsim.experiments.spec import Experiment, check_networks, check_renderer, check_run_names, load_experiment, located
from avsim.metrics import write_json_atomic
from avsim.realism.settings import BASELINE, SETTINGS

EXPERIMENTS_DIR = Path(__file__).resolve().parents[2] / "experiments"
# `avsim reproduce` (`make run`): the study's tables and figure, report order; 105 runs. Issue 25 gives
# `make run` 12 minutes on a 2-core machine: these four files need about 20 CPU-minutes (docs/reproducing.md),
# and the two additions that ran here before (the adaptive attacker and the wet road, 70 runs and about 12.5
# CPU-minutes more) did not fit, so they moved to `--all`.
STUDY_EXPERIMENTS = ("table3_stop_positions", "table1_clean_defended", "table2_attacked_defended", "fig3_detection")
# `avsim reproduce --all` adds every other experiment file: the additions beyond the study, the constant
# sensitivity, the COCO network's closed loop, and the attack files (experiments/attacks/); paths relative
# to EXPERIMENTS_DIR.
MORE_EXPERIMENTS = ("adaptive_attacker", "wet_road", "sensitivity", "sky_brightness", "table3_realism", "coco_detector",
                    "coco_detector_realism",
                    "table3_coco",
                    "attacks/success_town07", "attacks/success_towns", "attacks/range_inflation_adjusted",
                    "attacks/driveby_detector_town07", "attacks/success_coco", "attacks/success_coco_towns",
                    "attacks/sensitivity_coco_town10")
# The YOLOv3-tiny files, run by name (`--experiments`): YOLOv3-tiny is avsim's slowest perception (0.1-0.2x
# real time a run on this CPU; docs/yolo.md), and these 1355 runs would add hours to `--all`.
YOLO_EXPERIMENTS = ("yolo_detector", "table3_yolo", "table3_yolo_clusters", "attacks/success_yolo",
                    "attacks/success_yolo_towns", "attacks/sensitivity_yolo_town03", "attacks/success_yolo_textures",
                    "attacks/success_yolo_textures_town07", "attacks/success_yolo_textures_towns",
                    "attacks/driveby_yolo")
# Files of cells to run under a costly render setting (`--setting`), run by name: under the default renders each
# repeats another file's runs, config for config, and under `textured_aniso16` a run costs about 2 CPU-seconds a
# control step on llvmpipe (docs/realism_filtering.md).
SETTING_EXPERIMENTS = ("coco_detector_town10",)


def load_study(experiment_paths: list[Path] | None = None, quick: bool = False, everything: bool = False,
               yes: bool = False, seeds: int | None = None, setting: str = BASELINE,
               overrides: Mapping[str, Any] | None = None, cells: Sequence[str] | None = None) -> list[Experiment]:
    """The experiments to run: `experiment_paths`, or the study's (`everything`: and every other
    experiment file), with only the cells whose names match one of `cells` (shell-style patterns,
    `avsim.experiments.cell_selection`; None: every cell); `quick` keeps one seed per cell, `seeds`
    runs seeds 0 .. seeds - 1 in every cell instead of each file's own count. setting: one of
    `avsim realism`'s render settings, applied to every cell (`avsim.experiments.render_setting`).
    overrides: the --set values (nested, as `avsim.cli.overrides.parse_set` gives them), given to
    every cell over the setting (`avsim.experiments.set_overrides`). yes: allow a plan of more than
    `plan_size.RUNS_WITHOUT_YES` runs (counted before any run is built)."""
    if quick and seeds is not None:
        raise ConfigError("--quick runs one seed per cell and --seeds N runs N; give one of them")
    names = STUDY_EXPERIMENTS + (MORE_EXPERIMENTS if everything else ())
    paths = experiment_paths or [EXPERIMENTS_DIR / f"{name}.toml" for name in names]
    if setting not in SETTINGS:
        raise ConfigError(f"unknown render setting {setting!r}; choose one of {', '.join(SETTINGS)} (docs/realism.md)")
    setting_keys = SETTINGS[setting].keys
    experiments = select_cells([experiment_with_set(under_setting(load_experiment(path), SETTINGS[setting]),
                                                    overrides or {}, setting_keys) for path in paths], cells)
    stems = [e.path.stem for e in experiments]
    if len(set(stems)) != len(stems):
        raise ConfigError(f"two experiment files share a name ({', '.join(stems)}); their runs would mix in the results")
    if quick or seeds is not None:
        # A run's config depends on its seed alone, not on the count, so seed k is the same run either way.
        experiments = [dataclasses.replace(e, seeds=1 if quick else seeds) for e in experiments]
    runs = sum(e.size for e in experiments)
    check_plan_size(runs, f"the {len(experiments)} experiment file(s)", yes=yes)
    checked_signs: set[str] = set()
    for experiment in experiments:
        for cell in experiment.cells:
            # The sign texture too: a file may name one that is written after it (an attack's), but by now
            # every run needs it, and a missing or broken one would fail each run after the folder is made.
            # Each texture is decoded once (`--all` has 449 cells and a few textures); the other names were
            # checked per cell when the file loaded.
            if cell.config.scenario.sign not in checked_signs:
                with located(experiment.path, f'cell "{cell.name}"'):
                    check_run_names(cell.config)
                checked_signs.add(cell.config.scenario.sign)
            check_networks(cell.config)
            check_renderer(cell.config)
    return experiments


def specs_for(experiments: list[Experiment]) -> Plan:
    """Every (experiment, cell, seed) as a spec, built only as a batch draws on it (`avsim.experiments.plan`)."""
    return Plan(sum(e.size for e in experiments),
                lambda: (RunSpec(experiment.path.stem, run.cell_name, run.seed, run.config)
                         for experiment in experiments for run in experiment.iter_runs()))


def _fresh_dir(root: Path, stamp: str) -> Path:
    """A folder name under `root` that does not exist yet (made by `locked_output`)."""
    out = root / stamp
    suffix = 1
    while out.exists():
        suffix += 1
        out = root / f"{stamp}_{suffix}"
    return out


def reproduce(results_root: str | os.PathLike = "results", *, quick: bool = False, seeds: int | None = None,
              workers: int | None = None,
              experiment_paths: list[Path] | None = None, progress: bool = True, backend: str = "local",
              address: str | None = None, batch: int = DEFAULT_BATCH, everything: bool = False, yes: bool = False,
              rrd: str = DEFAULT_RRD, mcap: str = DEFAULT_MCAP, resume: str | os.PathLike | None = None,
              setting: str = BASELINE, overrides: Mapping[str, Any] | None = None,
              cells: Sequence[str] | None = None) -> Path:
    """Run the study's experiments (`everything`: and every other experiment file, `MORE_EXPERIMENTS`);
    returns the results folder (see the module docstring).

    seeds: run seeds 0 .. seeds - 1 in every cell instead of each file's own count (`quick`: one).

    setting: render every run under one of `avsim realism`'s settings (`avsim.realism.settings`), as if
    its keys stood in each file's [defaults]; a file that sets one of them itself is refused.

    overrides: `--set` values (nested: {"policy": {"conf_threshold": 0.55}}) given to every run, as if they
    stood in each file's [defaults]; a key on which a file's cells differ, or that [vary] draws, is refused
    (`avsim.experiments.set_overrides`).

    cells: run only the cells whose names match one of these shell-style patterns
    (`avsim.experiments.cell_selection`); None: every cell.

    resume: a results folder of an earlier `reproduce` to finish instead of making a new one under
    `results_root`: its ok runs are kept and the rest run (module docstring).

    rrd, mcap: which runs are recorded, "none", "failed" or "all" (`avsim.experiments.recordings`).

    backend, address: where the runs go (`avsim.experiments.batch.run_batch`); checked, like
    the experiment files and `workers`, before the results folder is made.
    """
    if everything and experiment_paths:
        raise ConfigError("--all runs every experiment file; leave out --experiments, or name the files without --all")
    overrides = dict(overrides or {})
    experiments = load_study(experiment_paths, quick, everything, yes, seeds, setting, overrides, cells)
    check_modes(rrd, mcap)
    check_backend(backend, address)
    workers = resolve_workers(workers, address)
    started = time.perf_counter()
    started_at = dt.datetime.now().astimezone()
    if resume is not None:
        out = Path(resume)
        existing = resumable_records(out)
        check_resumed_selection(out, experiments, yes=yes)
        check_resumed_cells(out, experiments, yes=yes)
        check_resumed_setting(out, experiments, existing, yes=yes)
        check_resumed_set(out, flat_items(overrides), allowed=yes, other_fix="add --yes to run the others into it")
    else:
        out = _fresh_dir(Path(results_root), started_at.strftime("%Y-%m-%dT%H-%M-%S"))
        existing = []
    selection = " ".join(part for part in (
        "--all" if everything else "", "--quick" if quick else "", f"--seeds {seeds}" if seeds is not None else "",
        "--experiments " + " ".join(map(str, experiment_paths)) if experiment_paths else "", cell_flags(cells),
        f"--setting {setting}" if setting != BASELINE else "", set_flags(overrides),
        f"--backend {backend}" if backend != "local" else "", f"--address {address}" if address else "",
        recording_flags(rrd, mcap).strip()) if part)
    # Every file it writes into the folder (the module docstring) is checked before the first run: a --resume
    # folder may hold a folder where its report goes. A start that fails before the first run (a Ray cluster that
    # cannot be reached) leaves no new folder.
    files = (REPRODUCE_RUNS, "manifest.json", "report.md", SET_FILE, CELLS_FILE, *FIGURE_FILES,
             *(f"experiments/{experiment.path.name}" for experiment in experiments))
    folders = recording_folders([experiment.path.stem for experiment in experiments], rrd=rrd, mcap=mcap)
    with locked_output(out, "avsim reproduce", results_name=REPRODUCE_RUNS, files=files, folders=folders):
        return _reproduce_into(out, experiments, existing, selection=selection, workers=workers, progress=progress,
                               backend=backend, address=address, started=started, started_at=started_at, batch=batch,
                               rrd=rrd, mcap=mcap, resumed=resume is not None, overrides=overrides, cells=cells)


def check_resumed_selection(folder: Path, experiments: list[Experiment], *, yes: bool) -> None:
    """A one-line ConfigError when a `--resume FOLDER` would add experiment files to FOLDER, unless `yes`.

    FOLDER/experiments/ holds a copy of every file whose runs the folder has, made before the first of them.
    A file outside that set is new work, perhaps hours of it: a bare `--resume` on a folder made with
    `--experiments` would start the whole study there. So adding files takes `yes`; the same files, or fewer
    (whose other records are kept), or files changed since (whose changed cells run again) do not.
    """
    held = {path.name for path in (folder / "experiments").glob("*.toml")}
    added = sorted({experiment.path.name for experiment in experiments} - held)
    if held and added and not yes:
        raise ConfigError(f"--resume {folder}: that folder reproduces {' '.join(sorted(held))} (its experiments/), and "
                          f"this command adds {' '.join(added)}; resume it with the selection that made it (the "
                          "command Ctrl-C printed, e.g. --experiments naming those files), or add --yes to run the "
                          "added files into it")


# Every key a render setting sets (`avsim.realism.settings`): where a folder's runs and this command's differ in
# one, the folder was made under another --setting.
SETTING_KEYS = tuple(sorted({key for setting in SETTINGS.values() for key in setting.keys}))


def check_resumed_setting(folder: Path, experiments: list[Experiment], existing: list[dict], *, yes: bool) -> None:
    """A one-line ConfigError when FOLDER's runs were drawn under another render setting than this command's,
    unless `yes`.

    Under another --setting every run's config differs, so a resume would run the whole selection again into the
    folder. One finished run of a cell this command also runs is compared, key by key over SETTING_KEYS, with the
    config this command gives the same run: a setting applies to every cell alike. `yes` lets it through, for a
    file that was itself changed in one of those keys since (its changed cells then run again, as any change does).
    """
    if yes:
        return
    by_name = {(experiment.name, cell.name): (experiment, cell) for experiment in experiments for cell in experiment.cells}
    for record in existing:
        found = by_name.get((record.get("experiment"), record.get("cell")))
        result = record.get("result") or {}
        if found is None or record.get("status") != "ok" or "config" not in result:
            continue
        experiment, cell = found
        asked = experiment.config_for(cell, record["seed"])
        for key in SETTING_KEYS:
            section, name = key.split(".")
            there = result["config"].get(section, {}).get(name)
            here = getattr(getattr(asked, section), name)
            if there is not None and there != here:
                raise ConfigError(f"--resume {folder}: its runs were drawn with {key} = {there!r} and this command's "
                                  f"with {here!r}, so every run would run again into it; give the --setting that made "
                                  f"the folder (its manifest.json's command names it), or add --yes if "
                                  f"{experiment.path.name} itself changed that key since")
        return


def resumable_records(folder: Path) -> list[dict]:
    """The records of the reproduction in `folder`, to finish it; a one-line ConfigError when
    `folder` is not one (no runs.jsonl), or its runs.jsonl is not avsim's or has a corrupt line."""
    runs = folder / REPRODUCE_RUNS
    if not runs.is_file():
        raise ConfigError(f"--resume {folder}: no runs.jsonl there, so it is not a folder `avsim reproduce` made; "
                          "name the results/<timestamp> folder of the reproduction to finish")
    return read_records(runs)


def _reproduce_into(out: Path, experiments: list[Experiment], existing: list[dict], *, selection: str,
                    workers: int | None, progress: bool, backend: str, address: str | None, started: float,
                    started_at: dt.datetime, batch: int, rrd: str, mcap: str, resumed: bool,
                    overrides: Mapping[str, Any], cells: Sequence[str] | None) -> Path:
    from avsim.experiments.reproduce_report import write_report

    history = manifest_history(out / "manifest.json") if resumed else []
    for experiment in experiments:
        shutil.copy2(experiment.path, _mkdir(out / "experiments") / experiment.path.name)
    record_set(out, flat_items(overrides))
    record_cells(out, cells, resumed=resumed)
    plan = specs_for(experiments).then(lambda specs: with_recordings(specs, out, rrd=rrd, mcap=mcap))
    nodes = cluster_nodes(backend, address)
    # Runs are matched by name as well as config: two experiment files may share a config.
    records, ran = run_resumable(plan, out / REPRODUCE_RUNS, existing, by_run=True, workers=workers, progress=progress,
                                 resume_command=" ".join(filter(None, ("avsim reproduce", selection, f"--resume {out}"))),
                                 description="reproduce", backend=backend, address=address, batch=batch)
    wall_s = time.perf_counter() - started
    manifest = {
        "command": " ".join(filter(None, ("avsim reproduce", selection, f"--resume {out}" if resumed else ""))),
        "backend": backend,
        "address": address,
        "started_at": started_at.isoformat(timespec="seconds"),
        "wall_s": round(wall_s, 1),
        "workers": workers,
        "runs": len(records),
        "ran": ran,
        "reused": len(records) - ran,
        "failed": sum(r["status"] == "failed" for r in records),
        "experiments": {e.path.stem: {"title": e.title, "seeds": e.seeds, "cells": [c.name for c in e.cells]}
                        for e in experiments},
        "versions": software_versions(),
        "cluster_nodes": nodes,
        "history": history,
    }
    write_json_atomic(out / "manifest.json", manifest)
    write_report(out, experiments, records, manifest)
    if records and manifest["failed"] == len(records):
        first = next(r["error"] for r in records if r["status"] == "failed")
        raise RunsFailedError(f"every one of the {len(records)} runs failed (the first: {first}); see {out / 'report.md'}")
    return out


def _mkdir(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path
