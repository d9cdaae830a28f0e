"""`avsim reproduce --cells PATTERN ...`: run only the cells of the chosen files whose names match.

A render setting or a --set value is often worth measuring on a few cells of a file before all of them: the
COCO closed loop's Town03 cells under `window_geometry`, say, which are 75 of `coco_detector.toml`'s 225 runs:

    avsim reproduce --experiments experiments/coco_detector.toml --cells 'Town03 *' --setting window_geometry

A pattern is matched against each cell's whole name as a shell matches a file name (`fnmatch.fnmatchcase`:
`*` any run of characters, `?` one, `[...]` one of a set; case counts). A cell runs when any pattern matches
it; a file left with no cell is not run, and a pattern that matches no cell of any file is refused, since it
is most likely a typing slip. Each run that does run is the run the whole file gives, config for config and
seed for seed, so its record is the same bit for bit.

The results folder keeps the patterns in `cells.json` (`CELLS_FILE`), so that a `--resume` that would run
cells the folder was not made with (a bare `--resume` would run the whole file) is refused without --yes.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import shlex
from collections.abc import Sequence
from pathlib import Path

from avsim.errors import ConfigError
from avsim.experiments.resumable import kept_value
from avsim.experiments.spec import Experiment
from avsim.metrics import write_json_atomic

CELLS_FILE = "cells.json"


def matches(name: str, patterns: Sequence[str]) -> bool:
    """Whether the cell name `name` matches any of `patterns` (module docstring)."""
    return any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns)


def select_cells(experiments: Sequence[Experiment], patterns: Sequence[str] | None) -> list[Experiment]:
    """`experiments` with only the cells that match one of `patterns`; a file with none left is dropped.
    None or no patterns: every cell. A one-line ConfigError for a pattern that matches no cell of any file."""
    if not patterns:
        return list(experiments)
    names = [cell.name for experiment in experiments for cell in experiment.cells]
    for pattern in patterns:
        if not any(matches(name, (pattern,)) for name in names):
            examples = ", ".join(f'"{name}"' for name in names[:3])
            raise ConfigError(f"--cells {shlex.quote(pattern)} matches no cell of the {len(experiments)} experiment "
                              f"file(s) (cells are named like {examples}); a pattern matches a whole name, case "
                              "counting, so quote it and add * where the name goes on, e.g. --cells 'Town03 *'")
    kept = [dataclasses.replace(experiment, cells=tuple(cell for cell in experiment.cells if matches(cell.name, patterns)))
            for experiment in experiments]
    return [experiment for experiment in kept if experiment.cells]


def cell_flags(patterns: Sequence[str] | None) -> str:
    """The --cells flag that gives `patterns` back, quoted for a shell ("" for none): for a manifest's command
    and the resume hint."""
    return " ".join(["--cells", *map(shlex.quote, patterns)]) if patterns else ""


def record_cells(folder: Path, patterns: Sequence[str] | None, *, resumed: bool) -> None:
    """Write into FOLDER's `CELLS_FILE` the patterns whose cells the folder now holds runs of, or remove it when
    that is every cell. A resume adds its `patterns` to those the folder was made with (the folder holds both);
    a folder made without --cells, or resumed without it, holds every cell."""
    if resumed:
        held = _held_patterns(folder)
        patterns = None if held is None or not patterns else [*held, *(p for p in patterns if p not in held)]
    if patterns:
        write_json_atomic(folder / CELLS_FILE, {"cells": list(patterns)})
    else:
        (folder / CELLS_FILE).unlink(missing_ok=True)


def check_resumed_cells(folder: Path, experiments: Sequence[Experiment], *, yes: bool) -> None:
    """A one-line ConfigError when a `--resume FOLDER` would run a cell that FOLDER's --cells did not select,
    unless `yes`. experiments: this command's, after its own --cells. The same cells or fewer are allowed."""
    made_with = _held_patterns(folder)
    if made_with is None or yes:
        return
    added = [f"{experiment.name}: {cell.name}" for experiment in experiments for cell in experiment.cells
             if not matches(cell.name, made_with)]
    if added:
        raise ConfigError(f"--resume {folder}: that folder was made with {cell_flags(made_with)}, and this command "
                          f"also runs {len(added)} other cell(s) (\"{added[0]}\"{', ...' if len(added) > 1 else ''}); "
                          "resume it with the same --cells (the command Ctrl-C printed names them), or add --yes to "
                          "run the others into it")


def _held_patterns(folder: Path) -> list[str] | None:
    """The --cells patterns FOLDER's runs were chosen by (None: every cell); a one-line ConfigError for a
    `CELLS_FILE` avsim did not write."""
    fix = "remove it if the folder was made without --cells"
    held = kept_value(folder, CELLS_FILE, "cells", list, None, "list of patterns", fix)
    if held is not None and not all(isinstance(pattern, str) for pattern in held):
        raise ConfigError(f"--resume {folder}: its {CELLS_FILE} is not one avsim wrote (a pattern that is not a "
                          f"string); {fix}")
    return held
