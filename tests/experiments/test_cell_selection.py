"""`avsim reproduce --cells`: only the matching cells run, each as the whole file runs it, and a resume keeps to them."""

import json

import pytest

from avsim import cli
from avsim.errors import ConfigError
from avsim.experiments.cell_selection import CELLS_FILE, cell_flags, check_resumed_cells, record_cells, select_cells
from avsim.experiments.reproduce import load_study
from avsim.experiments.results_file import read_records

# Short oracle runs: three cells in two towns, so a pattern can take a town's.
TINY = """
title = "cells stand-in"
seeds = 2
[defaults]
scenario = { placement = "standard", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 50 }
perception = { kind = "oracle" }
[[cells]]
name = "Town07 standard, baseline"
scenario = { town = "town07" }
policy = { name = "baseline" }
[[cells]]
name = "Town07 standard, autopilot"
scenario = { town = "town07" }
policy = { name = "autopilot" }
[[cells]]
name = "Town03 standard, baseline"
scenario = { town = "town03" }
policy = { name = "baseline" }
"""
# The first two cells again, in Town10.
OTHER = "[[cells]]".join(TINY.split("[[cells]]")[:3]).replace('title = "cells stand-in"', 'title = "other stand-in"'
                                                                ).replace("Town07", "Town10").replace("town07", "town10")


@pytest.fixture
def files(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "other.toml").write_text(OTHER)
    return [tmp_path / "tiny.toml", tmp_path / "other.toml"]


def _names(experiments):
    return {experiment.name: [cell.name for cell in experiment.cells] for experiment in experiments}


def test_only_the_matching_cells_are_kept_and_a_file_left_with_none_is_dropped(files):
    experiments = load_study(files)
    assert _names(select_cells(experiments, ["Town07 *"])) == {
        "tiny": ["Town07 standard, baseline", "Town07 standard, autopilot"]}
    assert _names(select_cells(experiments, ["*, baseline"])) == {
        "tiny": ["Town07 standard, baseline", "Town03 standard, baseline"], "other": ["Town10 standard, baseline"]}
    assert _names(select_cells(experiments, ["Town03 *", "Town10 standard, auto*"])) == {
        "tiny": ["Town03 standard, baseline"], "other": ["Town10 standard, autopilot"]}
    assert select_cells(experiments, None) == experiments and select_cells(experiments, []) == experiments
    # load_study counts the plan after the choice: 2 cells x 2 seeds.
    assert sum(e.size for e in load_study(files, cells=["Town07 *"])) == 4


def test_each_chosen_cell_gives_the_runs_the_whole_file_gives(files):
    whole = {(e.name, run.cell_name, run.seed): run.config for e in load_study(files) for run in e.iter_runs()}
    chosen = [(e.name, run.cell_name, run.seed, run.config) for e in load_study(files, cells=["*, baseline"])
              for run in e.iter_runs()]
    assert len(chosen) == 6
    for name, cell, seed, config in chosen:
        assert config == whole[(name, cell, seed)]


@pytest.mark.parametrize("pattern", ["town07 *", "Town07", "Town99 *"])
def test_a_pattern_that_matches_no_cell_is_refused_in_one_line(files, pattern):
    # A whole name, case counting: a lower-case town or a pattern with no * where the name goes on matches nothing.
    with pytest.raises(ConfigError) as error:
        load_study(files, cells=["Town03 *", pattern])
    message = str(error.value)
    assert "\n" not in message and f"matches no cell of the 2 experiment file(s)" in message
    assert "--cells 'Town03 *'" in message and "Town07 standard, baseline" in message


def test_the_flags_are_quoted_for_a_shell():
    assert cell_flags(["Town03 *", "x"]) == "--cells 'Town03 *' x"
    assert cell_flags(None) == cell_flags([]) == ""


def test_a_folder_keeps_its_patterns_and_a_resume_adds_its_own(tmp_path):
    record_cells(tmp_path, ["Town03 *"], resumed=False)
    assert json.loads((tmp_path / CELLS_FILE).read_text()) == {"cells": ["Town03 *"]}
    record_cells(tmp_path, ["Town10 *", "Town03 *"], resumed=True)
    assert json.loads((tmp_path / CELLS_FILE).read_text()) == {"cells": ["Town03 *", "Town10 *"]}
    record_cells(tmp_path, None, resumed=True)  # resumed with every cell: the folder now holds any
    assert not (tmp_path / CELLS_FILE).exists()
    record_cells(tmp_path, ["Town03 *"], resumed=True)  # a folder of every cell stays one
    assert not (tmp_path / CELLS_FILE).exists()


def test_a_resume_may_run_the_same_cells_or_fewer_and_more_need_yes(files, tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir()
    record_cells(folder, ["Town07 *", "Town10 *"], resumed=False)
    for patterns in (["Town07 *", "Town10 *"], ["Town07 standard, baseline"], ["Town10 *"]):
        check_resumed_cells(folder, load_study(files, cells=patterns), yes=False)
    with pytest.raises(ConfigError, match=r"made with --cells 'Town07 \*' 'Town10 \*', and this command also runs 1 "
                                          r"other cell\(s\) \(\"tiny: Town03 standard, baseline\"\)"):
        check_resumed_cells(folder, load_study(files), yes=False)
    check_resumed_cells(folder, load_study(files), yes=True)
    check_resumed_cells(tmp_path, load_study(files), yes=False)  # a folder made without --cells holds every cell


@pytest.mark.parametrize("text", ['{"cells": "Town03 *"}', '{"cells": [3]}', "not json"])
def test_a_cells_file_avsim_did_not_write_is_refused_in_one_line(files, tmp_path, text):
    (tmp_path / CELLS_FILE).write_text(text)
    with pytest.raises(ConfigError) as error:
        check_resumed_cells(tmp_path, load_study(files), yes=False)
    assert "\n" not in str(error.value) and "not one avsim wrote" in str(error.value)


def test_reproduce_runs_only_the_chosen_cells_and_a_bare_resume_is_refused(files, tmp_path, capsys):
    base = ["reproduce", "--experiments", *map(str, files), "--quick", "--workers", "1", "--no-progress",
            "--rrd", "none"]
    assert cli.main([*base, "--out", str(tmp_path / "results"), "--cells", "Town03 *", "Town10 standard, auto*"]) == 0
    (folder,) = (tmp_path / "results").iterdir()
    assert [(r["experiment"], r["cell"]) for r in read_records(folder / "runs.jsonl")] == [
        ("tiny", "Town03 standard, baseline"), ("other", "Town10 standard, autopilot")]
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["command"].endswith("--cells 'Town03 *' 'Town10 standard, auto*' --rrd none")
    assert manifest["experiments"]["tiny"]["cells"] == ["Town03 standard, baseline"]
    capsys.readouterr()

    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert cli.main([*base, "--resume", str(folder)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "also runs 3 other cell(s)" in err, err
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    # The same --cells resumes it, with every run already there.
    assert cli.main([*base, "--resume", str(folder), "--cells", "Town03 *", "Town10 standard, auto*"]) == 0
    assert json.loads((folder / "manifest.json").read_text())["ran"] == 0
