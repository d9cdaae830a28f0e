"""`avsim reproduce --set KEY=VALUE`: one config value given to every run of the experiment files.

A threshold's sensitivity, another network on the same cells, another road: each is one key changed over a
whole file, e.g.

    avsim reproduce --experiments experiments/coco_detector_town10.toml --set policy.conf_threshold=0.55

A --set key replaces the value the file gives all of its cells (from [defaults], or the same in each cell), so
each run's config is what a copy of the file with the key in [defaults] gives, and what
`avsim run --config FILE --cell C --seed K --set KEY=VALUE` gives the same run alone. What is refused, in one line
before anything runs:
- a key on which the file's cells differ (Table I's `policy.name`): the cells would run alike under names that
  say they differ; run one cell with `avsim run --set`, or edit a copy of the file;
- a key [vary] draws per seed: every draw would be replaced;
- a key no cell reads (a side-camera key over front-camera cells), and `scenario.seed`, which a batch sets per run;
- a key the command's --setting sets: the --set would quietly undo part of the setting.
"""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
from collections.abc import Mapping
from typing import Any

from avsim.config import with_overrides
from avsim.config_owners import check_read_by_some, dotted_keys
from avsim.errors import ConfigError
from avsim.experiments.spec import Cell, Experiment, located

# A string value that reads back as itself when written bare after `KEY=` (`avsim.cli.overrides.parse_set`
# reads a bare word as a string, but `true` or `inf` as TOML values).
_BARE_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
_TOML_WORDS = frozenset({"true", "false", "inf", "nan"})


def flat_items(overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A nested `--set` mapping ({"policy": {"conf_threshold": 0.55}}) as {dotted key: value}, sorted by key."""
    return {f"{section}.{key}": value for section, table in sorted(overrides.items()) if isinstance(table, Mapping)
            for key, value in sorted(table.items())}


def set_flags(overrides: Mapping[str, Any]) -> str:
    """The --set flags that give the nested `overrides` back, as a shell would pass them:
    "--set policy.conf_threshold=0.55" ("" for none), for a command line written into a manifest or a resume hint."""
    return flags_of_items(flat_items(overrides))


def flags_of_items(items: Mapping[str, Any]) -> str:
    """`set_flags` of {dotted key: value} (`flat_items`' form, as a results folder's set.json holds it)."""
    return " ".join(f"--set {shlex.quote(f'{key}={_as_typed(value)}')}" for key, value in items.items())


def _as_typed(value: Any) -> str:
    """`value` as it is typed after `KEY=`: a bare word for a plain string, TOML (which JSON's numbers, booleans,
    quoted strings and arrays are) for the rest."""
    if isinstance(value, str) and _BARE_WORD.fullmatch(value) and value not in _TOML_WORDS:
        return value
    return json.dumps(list(value) if isinstance(value, tuple) else value)


def experiment_with_set(experiment: Experiment, overrides: Mapping[str, Any], setting_keys: frozenset[str]) -> Experiment:
    """`experiment` with the `--set` `overrides` in every cell and its title naming them; the experiment itself
    for no overrides. setting_keys: the dotted keys the command's render setting sets (refused here). A one-line
    ConfigError, naming the file and the key, for each refusal in the module docstring."""
    if not overrides:
        return experiment
    keys = dotted_keys(overrides)  # empty for `--set policy=3`, which with_overrides refuses below
    path = experiment.path
    if "scenario.seed" in keys:
        raise ConfigError("--set scenario.seed: a batch gives each run its seed (0 .. seeds-1); give --seeds N for "
                          "more of them, or replay one run with `avsim run --config FILE --cell NAME --seed K`")
    try:  # every key and value, before any is looked up in the cells
        configs = [with_overrides(cell.config, overrides) for cell in experiment.cells]
    except ConfigError as exc:
        raise ConfigError(f"--set: {exc}") from None
    clash = keys & setting_keys
    if clash:
        raise ConfigError(f"--set {sorted(clash)[0]}: the command's --setting sets that key too; leave out one of them")
    drawn = keys & {key for key, _, _ in experiment.vary}
    if drawn:
        raise ConfigError(f"{path}: its [vary] draws {sorted(drawn)[0]} per seed, and --set would replace every draw; "
                          "edit a copy of the file's [vary] instead")
    for key in sorted(keys):
        section, name = key.split(".")
        values = {cell.name: getattr(getattr(cell.config, section), name) for cell in experiment.cells}
        if len(set(map(repr, values.values()))) > 1:
            (first, a), (second, b) = _two_differing(values)
            raise ConfigError(f"{path}: its cells differ in {key} (\"{first}\": {a!r}, \"{second}\": {b!r}), so --set "
                              f"would run them alike under names that say they differ; run one cell with `avsim run "
                              f"--config {path} --cell NAME --set {key}=...`, or edit a copy of the file")
    cells = [Cell(cell.name, config, cell.keys_set | keys) for cell, config in zip(experiment.cells, configs)]
    with located(path, "--set"):
        check_read_by_some((cell.config for cell in cells), keys, runs="cell")
    return dataclasses.replace(experiment, title=f"{experiment.title} (with {set_flags(overrides)})", cells=tuple(cells))


def _two_differing(values: dict[str, Any]) -> tuple[tuple[str, Any], tuple[str, Any]]:
    """The first cell's (name, value) and the first other cell's with another value."""
    items = list(values.items())
    first = items[0]
    return first, next(item for item in items[1:] if repr(item[1]) != repr(first[1]))
