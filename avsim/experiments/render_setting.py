"""An experiment file run under one of `avsim realism`'s render settings (`avsim reproduce --setting`).

A setting (`avsim.realism.settings.SETTINGS`: textured surfaces, see-through crowns, a daylight sky, a
camera preset, ...) is a group of config overrides. Applied over an experiment file it gives every cell
the same overrides, as if they stood in the file's [defaults]: each run's config, and so its config hash
and result, is what a copy of the file with those keys in [defaults] gives. A file that already sets one of
the setting's keys, in [defaults], a cell or [vary], is refused: the setting would silently replace the
file's own choice (Table III's `flat` cell would render textured), so the user must choose.
"""

from __future__ import annotations

import dataclasses

from avsim.config import with_overrides
from avsim.config_owners import dotted_keys
from avsim.errors import ConfigError
from avsim.experiments.spec import Cell, Experiment
from avsim.realism.settings import RenderSetting


def under_setting(experiment: Experiment, setting: RenderSetting) -> Experiment:
    """`experiment` with `setting`'s overrides in every cell, its title naming the setting; the
    experiment itself for a setting that changes nothing (`baseline`). ConfigError, naming the key and
    the cell, where the file sets a key the setting sets."""
    overrides = setting.config_overrides()
    setting_keys = dotted_keys(overrides)
    if not setting_keys:
        return experiment
    varied = setting_keys & {key for key, _, _ in experiment.vary}
    if varied:
        raise ConfigError(f"{experiment.path}: its [vary] draws {', '.join(sorted(varied))}, which --setting {setting.name} "
                          "sets; run the file without --setting, or choose a setting that leaves that key to the file")
    cells = []
    for cell in experiment.cells:
        clash = setting_keys & cell.keys_set
        if clash:
            raise ConfigError(f"{experiment.path}: cell \"{cell.name}\" sets {', '.join(sorted(clash))}, which --setting "
                              f"{setting.name} sets too; run the file without --setting, or choose a setting that leaves "
                              "that key to the file")
        try:
            config = with_overrides(cell.config, overrides)
        except ConfigError as exc:
            raise ConfigError(f"{experiment.path}: cell \"{cell.name}\" under --setting {setting.name}: {exc}") from None
        cells.append(Cell(cell.name, config, cell.keys_set | setting_keys))
    return dataclasses.replace(experiment, title=f"{experiment.title} (render setting {setting.name}: {setting.describe()})",
                               cells=tuple(cells))
