"""An experiment or leaderboard file run under one of `avsim realism`'s render settings
(`avsim reproduce`, `sweep`, `leaderboard` and `run`, each with `--setting NAME`).

A setting (`avsim.realism.settings.SETTINGS`: textured surfaces, see-through crowns, a daylight sky, a
camera preset, ...) is a group of config overrides. Applied over an experiment file it gives every cell
the same overrides, as if they stood in the file's [defaults]: each run's config, and so its config hash
and result, is what a copy of the file with those keys in [defaults] gives. A file that already sets one of
the setting's keys (in [defaults], a cell, [vary], a sweep's [grid], or a leaderboard's defence, condition
or availability scenario) is refused: the setting would silently replace the file's own choice (Table III's `flat` cell
would render textured), so the user must choose.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path

from avsim.config import with_overrides
from avsim.errors import ConfigError
from avsim.experiments.leaderboard import Leaderboard
from avsim.experiments.spec import Cell, Experiment
from avsim.experiments.sweep import Sweep
from avsim.realism.settings import RenderSetting


def under_setting(experiment: Experiment, setting: RenderSetting) -> Experiment:
    """`experiment` with `setting`'s overrides in every cell, its title naming the setting; the
    experiment itself for a setting that changes nothing (`baseline`). ConfigError, naming the key and
    the cell, where the file sets a key the setting sets."""
    overrides, setting_keys = setting.config_overrides(), setting.keys
    if not setting_keys:
        return experiment
    _refuse_clash(experiment.path, "its [vary]", {key for key, _, _ in experiment.vary}, setting)
    cells = []
    for cell in experiment.cells:
        _refuse_clash(experiment.path, f'cell "{cell.name}"', cell.keys_set, setting)
        try:
            config = with_overrides(cell.config, overrides)
        except ConfigError as exc:
            raise ConfigError(f"{experiment.path}: cell \"{cell.name}\" under --setting {setting.name}: {exc}") from None
        cells.append(Cell(cell.name, config, cell.keys_set | setting_keys))
    return dataclasses.replace(experiment, title=f"{experiment.title} (render setting {setting.name}: {setting.describe()})",
                               cells=tuple(cells))


def board_under_setting(board: Leaderboard, setting: RenderSetting) -> Leaderboard:
    """`board` with `setting`'s overrides under every run (in its base config, below each defence,
    condition, place and availability scenario), its title naming the setting; the board itself for
    `baseline`. ConfigError, naming the key and where the file sets it, where the file sets a key the
    setting sets."""
    return _base_under_setting(board, board.layers(), setting)


def sweep_under_setting(sweep: Sweep, setting: RenderSetting) -> Sweep:
    """`sweep` with `setting`'s overrides under every grid point (in its base config), its title naming
    the setting; the sweep itself for `baseline`. ConfigError where its [defaults] or [grid] sets a key
    the setting sets."""
    return _base_under_setting(sweep, sweep.layers(), setting)


def _base_under_setting(plan_file: Leaderboard | Sweep, layers: list[tuple[str, Iterable[str]]],
                        setting: RenderSetting) -> Leaderboard | Sweep:
    """A leaderboard or sweep (`path`, `title`, `base`, `setting`) with `setting`'s overrides in its base
    config, after refusing any of `layers` ((where, dotted keys it sets)) that sets one of them."""
    if not setting.keys:
        return plan_file
    for where, keys in layers:
        _refuse_clash(plan_file.path, where, keys, setting)
    try:
        base = with_overrides(plan_file.base, setting.config_overrides())
    except ConfigError as exc:
        raise ConfigError(f"{plan_file.path} under --setting {setting.name}: {exc}") from None
    return dataclasses.replace(plan_file, base=base, setting=setting.name,
                               title=f"{plan_file.title} (render setting {setting.name}: {setting.describe()})")


def _refuse_clash(path: Path, where: str, keys_set: Iterable[str], setting: RenderSetting) -> None:
    """A one-line ConfigError where `where` in the file at `path` sets one of `setting`'s keys."""
    clash = setting.keys & frozenset(keys_set)
    if clash:
        raise ConfigError(f"{path}: {where} sets {', '.join(sorted(clash))}, which --setting {setting.name} sets too; "
                          "run the file without --setting, or choose a setting that leaves that key to the file")
