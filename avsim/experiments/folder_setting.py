"""Which render setting a sweep's or leaderboard's results folder was run under, so that a `--resume` under
another one is refused.

Under another `--setting` every run's config differs from the folder's (each run's config hash is new), so a
resume would run the whole file again into the folder, beside the first runs, and its report would mix two
renderings. The folder keeps the setting's name in `setting.json` (`SETTING_FILE`), written only for a setting
other than `baseline`; a folder without it was run under the default renders. (`avsim reproduce` checks its
folders another way, from the configs in their records: `avsim.experiments.reproduce.check_resumed_setting`.)
"""

from __future__ import annotations

from pathlib import Path

from avsim.errors import ConfigError
from avsim.experiments.resumable import kept_value
from avsim.metrics import write_json_atomic
from avsim.realism.settings import BASELINE

SETTING_FILE = "setting.json"


def record_setting(folder: Path, setting: str) -> None:
    """Write `setting` (a name of `avsim.realism.settings.SETTINGS`) into FOLDER's `SETTING_FILE`, or remove the
    file for `baseline`."""
    if setting != BASELINE:
        write_json_atomic(folder / SETTING_FILE, {"setting": setting})
    else:
        (folder / SETTING_FILE).unlink(missing_ok=True)


def check_resumed_setting(folder: Path, setting: str, command: str) -> None:
    """A one-line ConfigError when FOLDER's runs were run under another render setting than `setting`;
    command: the command's name in the message ("avsim sweep")."""
    made_under = folder_setting(folder)
    if made_under != setting:
        raise ConfigError(f"--resume {folder}: its runs were rendered under --setting {made_under} and this "
                          f"{command} under --setting {setting}, so every run would run again into it; give "
                          f"--setting {made_under} to finish it, or another --out for these runs")


def folder_setting(folder: Path) -> str:
    """The render setting FOLDER's runs were run under (`baseline` for a folder without `SETTING_FILE`)."""
    return kept_value(folder, SETTING_FILE, "setting", str, BASELINE, "setting name",
                      "remove it if the folder was run under the default renders")
