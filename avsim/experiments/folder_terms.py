"""The terms a sweep's or leaderboard's results folder was run under (its `--setting` and its `--set` values), kept
in the folder so that a `--resume` under other terms is refused before it runs anything.

Under another `--setting` or other `--set` values every run's config differs from the folder's, so a resume would
run the whole file again into the folder beside the first runs, and its report would mix the two. Each term has
its own file and check (`avsim.experiments.folder_setting`, `avsim.experiments.set_overrides`); this module is
the one place that a sweep and a leaderboard, which are resumed alike, check and record both.
(`avsim reproduce` checks its folders another way, with `--yes` to run other cells into one.)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from avsim.experiments.folder_setting import check_resumed_setting, record_setting
from avsim.experiments.resumable import RESULTS_FILE, holds_runs
from avsim.experiments.set_overrides import check_resumed_set, record_set


class RunTerms(Protocol):
    """What a loaded sweep or leaderboard says about how its runs are made beyond its file."""

    setting: str  # the render setting (a name of `avsim.realism.settings.SETTINGS`)
    set_items: tuple[tuple[str, Any], ...]  # the --set values: (dotted key, value), sorted


def check_resumed_terms(folder: Path, terms: RunTerms, command: str) -> None:
    """A one-line ConfigError when FOLDER already holds runs made under another `--set` or `--setting` than
    `terms`; command: the command's name in the message ("avsim sweep"). A folder without runs passes: a first
    command under `--resume` has nothing to mix with."""
    if not holds_runs(folder / RESULTS_FILE):
        return
    check_resumed_set(folder, dict(terms.set_items), allowed=False, other_fix="give another --out for these runs")
    check_resumed_setting(folder, terms.setting, command)


def record_terms(folder: Path, terms: RunTerms) -> None:
    """Keep `terms` in FOLDER (which exists) for a later resume's check, before the first run is written."""
    record_set(folder, dict(terms.set_items))
    record_setting(folder, terms.setting)
