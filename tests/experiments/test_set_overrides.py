"""`avsim reproduce --set KEY=VALUE`: one config value over every cell of an experiment file, what a copy of the
file with the key in [defaults] runs, and the refusals that keep a --set from changing what a cell's name says."""

from __future__ import annotations

import shlex

import pytest

from avsim.cli.overrides import parse_set
from avsim.config import with_overrides
from avsim.config_owners import dotted_keys
from avsim.errors import ConfigError
from avsim.experiments.set_overrides import experiment_with_set, flat_items, set_flags
from avsim.experiments.spec import load_experiment
from avsim.realism.settings import SETTINGS

FILE = """
title = "A stand-in"
seeds = 2
[defaults]
scenario = {{ town = "town07", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 50{extra} }}
perception = {{ kind = "oracle" }}
policy = {{ a_max_mps2 = {a_max_mps2} }}
[vary]
scenario = {{ sun_elevation_deg = [30, 70] }}
[[cells]]
name = "adjusted"
policy = {{ name = "adjusted" }}
[[cells]]
name = "side camera"
policy = {{ name = "side_camera" }}
"""


def _write(tmp_path, name="stand_in.toml", extra="", a_max_mps2=8.0):
    path = tmp_path / name
    path.write_text(FILE.format(extra=extra, a_max_mps2=a_max_mps2))
    return path


def test_every_run_under_a_set_is_the_run_of_the_file_with_the_key_in_defaults(tmp_path):
    overrides = parse_set(["scenario.placement=far", "policy.a_max_mps2=6.5"])
    with_set = experiment_with_set(load_experiment(_write(tmp_path)), overrides, frozenset())
    by_hand = load_experiment(_write(tmp_path, "by_hand.toml", extra=', placement = "far"', a_max_mps2=6.5))
    assert with_set.runs() == by_hand.runs()  # configs, [vary] draws included
    assert with_set.runs()[0].config.scenario.placement == "far"
    assert "(with --set policy.a_max_mps2=6.5 --set scenario.placement=far)" in with_set.title
    assert all({"policy.a_max_mps2", "scenario.placement"} <= cell.keys_set for cell in with_set.cells)


def test_a_run_of_the_set_is_what_avsim_run_gives_the_same_cell_and_seed(tmp_path):
    # `avsim run --config FILE --cell C --seed K --set KEY=VALUE`: the cell's batch config at seed K, the --set on top.
    experiment = load_experiment(_write(tmp_path))
    overrides = parse_set(["policy.a_max_mps2=6.5"])
    with_set = experiment_with_set(experiment, overrides, frozenset())
    for run in with_set.runs():
        replayed = with_overrides(experiment.config_for(experiment.cell(run.cell_name), run.seed), overrides)
        assert run.config == replayed


def test_a_value_is_checked_against_the_files_config_not_the_defaults(tmp_path):
    # vote_k = 6 is over the default vote_n of 5, but within the file's vote_n of 8.
    path = tmp_path / "vote.toml"
    path.write_text(FILE.format(extra="", a_max_mps2=8.0).replace("a_max_mps2 = 8.0", "vote_n = 8")
                    .replace('name = "side_camera"', 'name = "temporal_vote"'))
    with_set = experiment_with_set(load_experiment(path), parse_set(["policy.vote_k=6"]), frozenset())
    assert {cell.config.policy.vote_k for cell in with_set.cells} == {6}
    with pytest.raises(ConfigError, match="--set: policy.vote_k and policy.vote_n must satisfy"):
        experiment_with_set(load_experiment(path), parse_set(["policy.vote_k=9"]), frozenset())


def test_no_set_leaves_the_experiment_as_it_is(tmp_path):
    experiment = load_experiment(_write(tmp_path))
    assert experiment_with_set(experiment, {}, frozenset()) is experiment


@pytest.mark.parametrize("items, expected", [
    (["scenario.seed=3"], "--set scenario.seed: a batch gives each run its seed"),
    (["policy.name=baseline"], 'its cells differ in policy.name ("adjusted": \'adjusted\', "side camera": '
                               "'side_camera')"),
    (["scenario.sun_elevation_deg=50"], "its [vary] sets scenario.sun_elevation_deg itself"),
    (["policy.no_such_key=1"], "--set: unknown config key 'policy.no_such_key'"),
    (["policy.a_max_mps2=fast"], "--set: "),
    (["policy=3"], "--set: config section 'policy' must be a table of keys"),
    (["perception.coco_input=upscale"], "--set: perception.coco_input is read only by"),  # no cell runs the COCO network
])
def test_a_set_that_would_change_what_a_cell_says_is_refused_in_one_line(tmp_path, items, expected):
    with pytest.raises(ConfigError) as refused:
        experiment_with_set(load_experiment(_write(tmp_path)), parse_set(items), frozenset())
    message = str(refused.value)
    assert expected in message and "\n" not in message, message


def test_a_set_of_a_key_the_setting_sets_is_refused(tmp_path):
    setting = SETTINGS["textured"]
    key = sorted(dotted_keys(setting.config_overrides()))[0]
    with pytest.raises(ConfigError, match=f"--set {key}: the command's --setting sets that key too"):
        experiment_with_set(load_experiment(_write(tmp_path)), parse_set([f"{key}=flat"]),
                            dotted_keys(setting.config_overrides()))


@pytest.mark.parametrize("overrides", [
    {"policy": {"conf_threshold": 0.55, "name": "adjusted"}},
    {"scenario": {"town": "true", "start_dist_m": 60, "materials": "two words"}, "perception": {"kind": "nanodet"}},
    {"policy": {"flag": True, "values": [1, 2.5], "empty": "", "word": "nan"}},
])
def test_the_set_flags_written_into_a_manifest_read_back_as_the_same_values(overrides):
    flags = shlex.split(set_flags(overrides))
    assert flags[::2] == ["--set"] * len(flat_items(overrides))
    assert parse_set(flags[1::2]) == overrides

