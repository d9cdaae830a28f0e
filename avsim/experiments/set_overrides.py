"""`--set KEY=VALUE` on `avsim reproduce`, `sweep` and `leaderboard`: one config value given to every run of a file.

A threshold's sensitivity, another network on the same cells, another road: each is one key changed over a
whole file, e.g.

    avsim reproduce --experiments experiments/coco_detector_town10.toml --set policy.conf_threshold=0.55
    avsim leaderboard --quick --set perception.kind=nanodet

A --set key replaces the value the file's [defaults] gives (or, in an experiment file, the value all of its cells
share), so each run's config is what a copy of the file with the key in [defaults] gives, and what
`avsim run --config FILE --cell C --seed K --set KEY=VALUE` gives one experiment run alone. What is refused, in one
line before anything runs:
- a key on which an experiment file's cells differ (Table I's `policy.name`): the cells would run alike under
  names that say they differ; run one cell with `avsim run --set`, or edit a copy of the file;
- a key a sweep's [grid], a leaderboard's defence, condition, place or availability scenario, or any file's
  [vary] sets: those runs would take the file's value over the --set, or every draw would be replaced;
- a key no run reads (a side-camera key over front-camera cells), and `scenario.seed`, which a batch sets per run;
- a key the command's --setting sets: the --set would quietly undo part of the setting.

The results folder keeps the values in `set.json` (`SET_FILE`), so that a `--resume` with other values, which
would run every run again into the folder beside the first ones, is refused.
"""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from avsim.config import with_overrides
from avsim.config_owners import check_read_by_some, dotted_keys
from avsim.errors import ConfigError
from avsim.experiments.resumable import kept_value
from avsim.experiments.spec import Cell, Experiment, located
from avsim.metrics import write_json_atomic

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


def checked_set(overrides: Mapping[str, Any], setting_keys: frozenset[str] = frozenset()) -> frozenset[str]:
    """The dotted keys of the nested `--set` `overrides`, after the refusals every file shares: `scenario.seed`,
    a key the command's --setting sets (`setting_keys`). One-line ConfigErrors. (Each key and value is checked
    where it is applied to the file's configs: a limit that ties two keys, vote_k <= vote_n, depends on them.)"""
    keys = dotted_keys(overrides)
    if "scenario.seed" in keys:
        raise ConfigError("--set scenario.seed: a batch gives each run its seed (0 .. seeds - 1); give the file more "
                          "seeds (`avsim reproduce --seeds N`), or replay one run with `avsim run ... --seed K`")
    clash = keys & setting_keys
    if clash:
        raise ConfigError(f"--set {sorted(clash)[0]}: the command's --setting sets that key too; leave out one of them")
    return keys


def refuse_layered(path: Path, keys: frozenset[str], layers: list[tuple[str, frozenset[str]]]) -> None:
    """A one-line ConfigError where one of `layers` ((where in the file, the dotted keys it sets), e.g.
    ("[grid]", {"scenario.speed_kmh"})) sets one of the --set `keys`: its runs would take the file's value."""
    for where, layer_keys in layers:
        clash = keys & layer_keys
        if clash:
            key = sorted(clash)[0]
            raise ConfigError(f"{path}: {where} sets {key} itself, and its runs would take that over --set {key}; "
                              "leave the key to the file, or edit a copy of it")


def set_title(title: str, overrides: Mapping[str, Any]) -> str:
    """A file's title with the --set values its runs were given, for the reports' headings."""
    return f"{title} (with {set_flags(overrides)})"


def experiment_with_set(experiment: Experiment, overrides: Mapping[str, Any], setting_keys: frozenset[str]) -> Experiment:
    """`experiment` with the `--set` `overrides` in every cell and its title naming them; the experiment itself
    for no overrides. setting_keys: the dotted keys the command's render setting sets (refused here). A one-line
    ConfigError, naming the file and the key, for each refusal in the module docstring."""
    if not overrides:
        return experiment
    keys = checked_set(overrides, setting_keys)
    path = experiment.path
    with located(path, "--set"):  # every key and value, before any is looked up in the cells
        configs = [with_overrides(cell.config, overrides) for cell in experiment.cells]
    refuse_layered(path, keys, [("its [vary]", frozenset(key for key, _, _ in experiment.vary))])
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
    return dataclasses.replace(experiment, title=set_title(experiment.title, overrides), cells=tuple(cells))


def _two_differing(values: dict[str, Any]) -> tuple[tuple[str, Any], tuple[str, Any]]:
    """The first cell's (name, value) and the first other cell's with another value."""
    items = list(values.items())
    first = items[0]
    return first, next(item for item in items[1:] if repr(item[1]) != repr(first[1]))


# The file in a results folder that holds the --set values its runs were given, written before the first run:
# a resume without them (or with others) would run every run again into the folder, beside the first ones.
SET_FILE = "set.json"


def record_set(folder: Path, items: Mapping[str, Any]) -> None:
    """Write {dotted key: value} (`flat_items`) into FOLDER's `SET_FILE`, or remove it for none."""
    if items:
        write_json_atomic(folder / SET_FILE, {"set": dict(items)})
    else:
        (folder / SET_FILE).unlink(missing_ok=True)  # a resume allowed without --set: the runs to come have none


def check_resumed_set(folder: Path, items: Mapping[str, Any], *, allowed: bool, other_fix: str) -> None:
    """A one-line ConfigError when FOLDER's runs were given other --set values than `items` ({dotted key: value}),
    unless `allowed`; other_fix: the message's last way out ("add --yes to run the others into it")."""
    made_with = _folder_set(folder)
    asked = json.loads(json.dumps(dict(items)))  # as JSON holds them: a list for a tuple
    if made_with != asked and not allowed:
        made = flags_of_items(made_with) or "no --set"
        this = flags_of_items(items) or "no --set"
        raise ConfigError(f"--resume {folder}: its runs were given {made} and this command {this}, so every run "
                          f"would run again into it; give the --set that made the folder (its {SET_FILE} and the "
                          f"command Ctrl-C printed name it), or {other_fix}")


def _folder_set(folder: Path) -> dict[str, Any]:
    """The --set values FOLDER's runs were given ({} for a folder made without them)."""
    return kept_value(folder, SET_FILE, "set", dict, {}, "table of keys", "remove it if the folder was made without --set")
