"""The terms a sweep's or leaderboard's results folder was run under (its `--setting` and its `--set` values), kept
in the folder so that a `--resume` under other terms is refused before it runs anything; and what the folder holds,
so that another command's folder, another plan's, or a folder that is not there is refused too.

Under another `--setting` or other `--set` values every run's config differs from the folder's, so a resume would
run the whole file again into the folder beside the first runs, and its report would mix the two. Each term has
its own file and check (`avsim.experiments.folder_setting`, `avsim.experiments.set_overrides`); this module is
the one place that a sweep and a leaderboard, which are resumed alike, check and record both.
(`avsim reproduce` checks its folders another way, with `--yes` to run other cells into one.)

Runs are found again by their config alone, so without these checks a resume with another sweep file counted the
folder's runs of the same config as its own (and replaced its sweep.toml), and a leaderboard resumed a sweep's
folder. A file edited since (a grid grown by a speed) is the same plan, named alike, and resumes.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Protocol

from avsim.errors import ConfigError
from avsim.experiments.folder_setting import check_resumed_setting, record_setting
from avsim.experiments.resumable import RESULTS_FILE, holds_runs
from avsim.experiments.set_overrides import check_resumed_set, record_set


class RunTerms(Protocol):
    """What a loaded sweep or leaderboard says about how its runs are made beyond its file."""

    setting: str  # the render setting (a name of `avsim.realism.settings.SETTINGS`)
    set_items: tuple[tuple[str, Any], ...]  # the --set values: (dotted key, value), sorted


# The file each batch command writes into the folder it runs in (a sweep's and a leaderboard's copy of their file,
# reproduce's run records), and so the command that made a folder.
SWEEP_COPY, LEADERBOARD_COPY, REPRODUCE_RUNS = "sweep.toml", "leaderboard.toml", "runs.jsonl"
MADE_BY = {SWEEP_COPY: "avsim sweep", LEADERBOARD_COPY: "avsim leaderboard", REPRODUCE_RUNS: "avsim reproduce"}


def check_made_by(folder: Path, command: str) -> None:
    """A one-line ConfigError when FOLDER holds another batch command's results than `command`'s ("avsim sweep"),
    with `--resume` or without: its manifest.json and report would be replaced, its records taken for this one's."""
    for name, maker in MADE_BY.items():
        if maker != command and (folder / name).exists():
            raise ConfigError(f"{folder} holds the results of {maker} (its {name}), not of {command}; give this "
                              f"command another --out (that folder resumes with {maker})")


def check_resumed_terms(folder: Path, terms: RunTerms, command: str) -> None:
    """A one-line ConfigError when FOLDER does not exist, or already holds runs made under another `--set` or
    `--setting` than `terms`; command: the command's name in the message ("avsim sweep"). A folder without runs
    passes: a first command under `--resume` has nothing to mix with."""
    if not folder.is_dir():  # a mistyped folder would start the whole plan afresh, as `avsim reproduce` refuses too
        raise ConfigError(f"--resume {folder}: no such folder, so there is nothing to resume; name the folder to "
                          "finish, or leave out --resume to start a new one")
    if not holds_runs(folder / RESULTS_FILE):
        return
    check_resumed_set(folder, dict(terms.set_items), allowed=False, other_fix="give another --out for these runs")
    check_resumed_setting(folder, terms.setting, command)


def record_terms(folder: Path, terms: RunTerms) -> None:
    """Keep `terms` in FOLDER (which exists) for a later resume's check, before the first run is written."""
    record_set(folder, dict(terms.set_items))
    record_setting(folder, terms.setting)


def check_resumed_plan(folder: Path, existing: Iterable[Mapping[str, Any]], plan: Path, name: str, copy_name: str) -> None:
    """A one-line ConfigError when FOLDER's records (`existing`) are the runs of another plan than the file `plan`
    (named `name`, its stem): each record names the file that made it (its `experiment`). The folder's own copy of
    that file (`copy_name`, "sweep.toml") is the same plan under another name, and passes."""
    held = sorted({str(r["experiment"]) for r in existing if r.get("experiment")})
    if not held or name in held:
        return
    copy = folder / copy_name
    if copy.is_file() and plan.is_file() and copy.read_bytes() == plan.read_bytes():
        return
    made = f"'{held[0]}' ({copy} is a copy of it)" if copy.is_file() else f"'{held[0]}'"
    raise ConfigError(f"--resume {folder}: it holds the runs of {made}, another plan than {plan}, which would count "
                      f"them as its own; resume it with the file that made it, or give {plan.name} another --out")
