"""An experiment, sweep or leaderboard file under a render setting (`avsim reproduce`, `run`, `sweep` and
`leaderboard`, each with `--setting`): the same configs as the file with the setting's keys in [defaults],
and a refusal where the file sets one of them itself."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from avsim import cli
from avsim.errors import ConfigError
from avsim.experiments.leaderboard import load_leaderboard
from avsim.experiments.render_setting import board_under_setting, sweep_under_setting, under_setting
from avsim.experiments.reproduce import reproduce
from avsim.experiments.results_file import read_records
from avsim.experiments.spec import load_experiment
from avsim.experiments.sweep import load_sweep
from avsim.realism.settings import SETTINGS

FILE = """
title = "A stand-in"
seeds = 2
[defaults]
scenario = {{ town = "town07", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 50{extra} }}
perception = {{ kind = "oracle" }}
[vary]
scenario = {{ sun_elevation_deg = [30, 70]{vary} }}
[[cells]]
name = "baseline"
policy = {{ name = "baseline" }}
[[cells]]
name = "side camera"
policy = {{ name = "side_camera" }}
{cell}
"""


def _write(tmp_path, name="stand_in.toml", extra="", vary="", cell=""):
    path = tmp_path / name
    path.write_text(FILE.format(extra=extra, vary=vary, cell=cell))
    return path


def test_every_run_under_a_setting_is_the_run_of_the_file_with_its_keys_in_defaults(tmp_path):
    setting = SETTINGS["full_scene_no_shadows"]
    keys = ", ".join(f'{key} = "{value}"' for key, value in setting.overrides["scenario"].items())
    under = under_setting(load_experiment(_write(tmp_path)), setting)
    by_hand = load_experiment(_write(tmp_path, "by_hand.toml", extra=", " + keys))
    assert under.runs() == by_hand.runs()  # configs, [vary] draws included
    assert under.runs()[0].config.scenario.foliage == "clusters"
    assert "full_scene_no_shadows" in under.title and "scenario.sky=daylight" in under.title


def test_the_baseline_setting_leaves_the_experiment_as_it_is(tmp_path):
    experiment = load_experiment(_write(tmp_path))
    assert under_setting(experiment, SETTINGS["baseline"]) is experiment


@pytest.mark.parametrize("where, file_args", [
    ('cell "flat"', {"cell": '[[cells]]\nname = "flat"\nscenario = { materials = "flat" }\npolicy = { name = "baseline" }'}),
    ('cell "baseline"', {"extra": ', materials = "flat"'}),  # [defaults] reach every cell
    ("[vary]", {"vary": ", road_friction = [0.5, 0.9]"}),
])
def test_a_file_that_sets_a_key_of_the_setting_is_refused_naming_the_key(tmp_path, where, file_args):
    experiment = load_experiment(_write(tmp_path, **file_args))
    setting = SETTINGS["textured"] if "vary" not in file_args else _road_setting()
    with pytest.raises(ConfigError) as err:
        under_setting(experiment, setting)
    message = str(err.value)
    assert where in message and ("scenario.materials" in message or "scenario.road_friction" in message)
    assert "without --setting" in message and "\n" not in message


def _road_setting():
    """A setting over a key the stand-in's [vary] can draw (no shipped setting sets a drawn key)."""
    from avsim.realism.settings import RenderSetting

    return RenderSetting("wet", {"scenario": {"road_friction": 0.5}}, "a wet road")


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    """A reproduction of the stand-in under `worn_paint`: (the file, the results folder)."""
    root = tmp_path_factory.mktemp("under_setting")
    path = _write(root)
    return path, reproduce(root / "results", workers=1, experiment_paths=[path], progress=False, rrd="none",
                           setting="worn_paint")


def test_reproduce_under_a_setting_runs_it_and_says_so(batch):
    _, out = batch
    records = read_records(out / "runs.jsonl")
    assert len(records) == 4 and all(r["status"] == "ok" for r in records)
    assert all(r["result"]["config"]["scenario"]["road_paint"] == "worn" for r in records)
    manifest = json.loads((out / "manifest.json").read_text())
    assert "--setting worn_paint" in manifest["command"]
    assert "render setting worn_paint" in manifest["experiments"]["stand_in"]["title"]
    assert "render setting worn_paint" in (out / "report.md").read_text()


def test_avsim_run_with_the_same_setting_replays_a_batched_run_bit_for_bit(batch, tmp_path):
    path, out = batch
    target = next(r for r in read_records(out / "runs.jsonl") if r["cell"] == "side camera" and r["seed"] == 1)
    result_json = tmp_path / "again.json"
    code = cli.main(["run", "--config", str(path), "--cell", "side camera", "--seed", "1", "--setting", "worn_paint",
                     "--json", str(result_json)])
    assert code == 0 and json.loads(result_json.read_text()) == target["result"]


@pytest.mark.parametrize("argv, expected", [
    (["--setting", "textured", "--set", "scenario.materials=flat"], "scenario.materials is set by --setting textured"),
    (["--config", "RESULTS", "--cell", "baseline", "--setting", "clusters"], "leave out --setting"),
    (["--config", "FILE", "--setting", "worn_paint", "--set", "scenario.road_paint=fresh"], "scenario.road_paint is set"),
])
def test_avsim_run_refuses_a_setting_the_flags_or_a_results_file_would_undo(batch, tmp_path, capsys, argv, expected):
    path, out = batch
    argv = [str(out / "runs.jsonl") if a == "RESULTS" else str(path) if a == "FILE" else a for a in argv]
    code = cli.main(["run", *argv, "--json", str(tmp_path / "run.json")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and expected in err
    assert not list(tmp_path.iterdir())


def test_a_refused_setting_fails_in_one_line_and_writes_nothing(tmp_path, capsys):
    path = _write(tmp_path, extra=', materials = "flat"')
    code = cli.main(["reproduce", "--experiments", str(path), "--setting", "textured", "--out", str(tmp_path / "results")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "scenario.materials" in err
    assert not (tmp_path / "results").exists()


# ---- a leaderboard under a setting -----------------------------------------------------------------

BOARD = """
title = "tiny board"
[defaults]
scenario = {{ town = "town07", placement = "standard", speed_kmh = 85, start_speed_kmh = 85, start_dist_m = 70 }}
perception = {{ kind = "oracle" }}
[conditions.clean]
scenario = {{ sign = "clean" }}
[conditions.strongest]
scenario = {{ sign = "yang" }}
[[defences]]
name = "baseline"
policy = {{ name = "baseline" }}
adaptive = {{ scenario = {{ sign = "yang"{adaptive} }} }}
[[places]]
town = "town07"
placement = "standard"
seeds = 1
quick_seeds = 1
[[availability]]
name = "no stop sign"
scenario = {{ sign = "none" }}
seeds = 1
"""
LEADERBOARDS = Path(__file__).resolve().parents[2] / "experiments" / "leaderboards"


def test_a_board_under_a_setting_is_the_board_with_its_keys_in_defaults():
    # The shipped see-through-crowns board is the three-network board with one key added to [defaults].
    under = board_under_setting(load_leaderboard(LEADERBOARDS / "three_networks.toml"), SETTINGS["clusters"])
    by_hand = load_leaderboard(LEADERBOARDS / "three_networks_clusters.toml")
    assert [(r.label, r.seed, r.config) for r in under.runs()] == [(r.label, r.seed, r.config) for r in by_hand.runs()]
    assert under.setting == "clusters" and "render setting clusters" in under.title


def test_a_board_that_sets_a_key_of_the_setting_is_refused_naming_where(tmp_path):
    path = tmp_path / "board.toml"
    path.write_text(BOARD.format(adaptive=', road_paint = "fresh"'))
    with pytest.raises(ConfigError, match='defence "baseline"\'s adaptive condition sets scenario.road_paint'):
        board_under_setting(load_leaderboard(path), SETTINGS["worn_paint"])


def test_avsim_leaderboard_under_a_setting_runs_it_and_says_so(tmp_path, capsys):
    path = tmp_path / "board.toml"
    path.write_text(BOARD.format(adaptive=""))
    out = tmp_path / "out"
    assert cli.main(["leaderboard", str(path), "--out", str(out), "--workers", "1", "--no-progress", "--rrd", "none",
                     "--setting", "worn_paint"]) == 0
    records = read_records(out / "results.jsonl")
    assert records and all(r["result"]["config"]["scenario"]["road_paint"] == "worn" for r in records)
    assert "--setting worn_paint" in json.loads((out / "manifest.json").read_text())["command"]
    assert "render setting worn_paint" in (out / "leaderboard.md").read_text()
    _assert_a_resume_must_give_the_setting(["leaderboard", str(path), "--out", str(out), "--workers", "1", "--no-progress",
                                            "--rrd", "none", "--resume"], out, capsys)


def test_avsim_leaderboard_refuses_a_setting_its_file_sets_in_one_line_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["leaderboard", str(LEADERBOARDS / "three_networks_clusters.toml"), "--out", str(out),
                     "--setting", "clusters"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "[defaults] sets scenario.foliage" in err
    assert not out.exists()


# ---- a sweep under a setting ------------------------------------------------------------------------

SWEEPS = Path(__file__).resolve().parents[2] / "experiments" / "sweeps"


def test_a_sweep_under_a_setting_is_the_sweep_with_its_keys_in_defaults(tmp_path):
    text = (SWEEPS / "sweep_smoke.toml").read_text()
    by_hand_path = tmp_path / "by_hand.toml"
    by_hand_path.write_text(text.replace('start_dist_m = 60 }', 'start_dist_m = 60, road_paint = "worn" }'))
    under = sweep_under_setting(load_sweep(SWEEPS / "sweep_smoke.toml"), SETTINGS["worn_paint"])
    assert [r.config for r in under.runs()] == [r.config for r in load_sweep(by_hand_path).runs()]
    assert under.setting == "worn_paint" and "render setting worn_paint" in under.title


def test_a_sweep_whose_grid_sets_a_key_of_the_setting_is_refused(tmp_path):
    path = tmp_path / "grid.toml"
    path.write_text((SWEEPS / "sweep_smoke.toml").read_text() + '"scenario.foliage" = ["solid", "clusters"]\n')
    with pytest.raises(ConfigError, match=r"\[grid\] sets scenario.foliage, which --setting clusters sets too"):
        sweep_under_setting(load_sweep(path), SETTINGS["clusters"])


def test_avsim_sweep_under_a_setting_runs_it_and_says_so(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sweep", str(SWEEPS / "sweep_smoke.toml"), "--out", str(out), "--workers", "1", "--no-progress",
                     "--rrd", "none", "--setting", "worn_paint"]) == 0
    records = read_records(out / "results.jsonl")
    assert len(records) == 4 and all(r["result"]["config"]["scenario"]["road_paint"] == "worn" for r in records)
    assert "--setting worn_paint" in json.loads((out / "manifest.json").read_text())["command"]
    _assert_a_resume_must_give_the_setting(["sweep", str(SWEEPS / "sweep_smoke.toml"), "--out", str(out), "--workers",
                                            "1", "--no-progress", "--rrd", "none", "--resume"], out, capsys)


def _assert_a_resume_must_give_the_setting(resume: list[str], out: Path, capsys) -> None:
    """The folder `out`, run under `worn_paint`, keeps the setting's name, and the `resume` command refuses it in one
    line, writing nothing, unless it gives the setting again; then it runs nothing."""
    assert json.loads((out / "setting.json").read_text()) == {"setting": "worn_paint"}
    capsys.readouterr()
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert cli.main(resume) == 2  # under the default renders every run would run again, beside the first ones
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "rendered under --setting worn_paint" in err and "give --setting worn_paint" in err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert cli.main([*resume, "--setting", "worn_paint"]) == 0
    assert json.loads((out / "manifest.json").read_text())["ran"] == 0
    capsys.readouterr()
