"""A sweep's or leaderboard's folder keeps its --setting and --set values together, and a resume that holds runs
is refused under other ones, while a folder without runs is not."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest

from avsim.errors import ConfigError
from avsim.experiments.folder_setting import SETTING_FILE
from avsim.experiments.folder_terms import check_made_by, check_resumed_plan, check_resumed_terms, record_terms
from avsim.experiments.resumable import RESULTS_FILE
from avsim.experiments.set_overrides import SET_FILE


@dataclass(frozen=True)
class Terms:
    setting: str = "baseline"
    set_items: tuple[tuple[str, Any], ...] = ()


MADE = Terms("sheeting", (("scenario.speed_kmh", 60.0),))


def _folder_with_runs(tmp_path):
    record_terms(tmp_path, MADE)
    (tmp_path / RESULTS_FILE).write_text('{"cell": "a"}\n')
    return tmp_path


def test_both_terms_are_kept_and_the_same_terms_resume(tmp_path):
    folder = _folder_with_runs(tmp_path)
    assert (folder / SETTING_FILE).is_file() and (folder / SET_FILE).is_file()
    check_resumed_terms(folder, MADE, "avsim sweep")


@pytest.mark.parametrize("other, named", [
    (Terms("sheeting"), "given --set scenario.speed_kmh=60.0 and this command no --set"),
    (Terms("baseline", MADE.set_items), "--setting sheeting and this avsim sweep under --setting baseline"),
])
def test_a_resume_under_other_terms_is_refused_in_one_line(tmp_path, other, named):
    folder = _folder_with_runs(tmp_path)
    with pytest.raises(ConfigError, match=named) as caught:
        check_resumed_terms(folder, other, "avsim sweep")
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("results", [None, ""], ids=["no results file", "an empty one"])
def test_a_folder_without_runs_is_not_refused(tmp_path, results):
    record_terms(tmp_path, MADE)
    if results is not None:
        (tmp_path / RESULTS_FILE).write_text(results)
    check_resumed_terms(tmp_path, Terms(), "avsim leaderboard")


def test_the_default_terms_leave_no_files(tmp_path):
    record_terms(tmp_path, MADE)
    record_terms(tmp_path, Terms())
    assert not (tmp_path / SETTING_FILE).exists() and not (tmp_path / SET_FILE).exists()


def test_a_resume_takes_its_own_plan_edited_or_copied_and_refuses_another_plan_or_a_missing_folder(tmp_path):
    plan = tmp_path / "speeds.toml"
    plan.write_text("[grid]\n'scenario.speed_kmh' = [40, 60]\n")
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "sweep.toml").write_text(plan.read_text())
    held = [{"experiment": "speeds", "spec_hash": "h0"}]
    plan.write_text("[grid]\n'scenario.speed_kmh' = [40, 60, 80]\n")  # the same file, its grid grown
    check_resumed_plan(folder, held, plan, "speeds", "sweep.toml")
    check_resumed_plan(folder, held, folder / "sweep.toml", "sweep", "sweep.toml")  # the folder's own copy
    other = tmp_path / "other.toml"
    other.write_text("[grid]\n'scenario.speed_kmh' = [30, 50]\n")
    with pytest.raises(ConfigError, match="holds the runs of 'speeds' .*another plan than .*other.toml"):
        check_resumed_plan(folder, held, other, "other", "sweep.toml")
    with pytest.raises(ConfigError, match="no such folder"):
        check_resumed_terms(tmp_path / "typo", MADE, "avsim sweep")
    check_made_by(folder, "avsim sweep")
    with pytest.raises(ConfigError, match="holds the results of avsim sweep"):
        check_made_by(folder, "avsim leaderboard")
