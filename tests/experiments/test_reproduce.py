"""`avsim reproduce` on a tiny, fast stand-in for the study's Table III (oracle perception, short runs)."""

import json
import shutil

import pytest

from avsim import cli
from avsim.errors import ConfigError
from avsim.experiments.recordings import slug
from avsim.experiments.reproduce import (EXPERIMENTS_DIR, MORE_EXPERIMENTS, SETTING_EXPERIMENTS, STUDY_EXPERIMENTS,
                                         YOLO_EXPERIMENTS, check_resumed_selection, check_resumed_setting, load_study,
                                         reproduce)
from avsim.experiments.results_file import encode, read_records

# The study's Table III cell names, so the report sets them beside the study's figures.
TINY_TABLE3 = """
title = "Table III stand-in"
seeds = 2
report = "table3"
[defaults]
scenario = { town = "town07", placement = "standard", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 50 }
perception = { kind = "oracle" }
[[cells]]
name = "clean sign, baseline"
policy = { name = "baseline" }
[[cells]]
name = "attacked sign, side_camera"
policy = { name = "side_camera" }
[[cells]]
name = "autopilot"
policy = { name = "autopilot" }
"""
TINY_FIG3 = """
title = "Fig. 3 stand-in"
seeds = 1
report = "fig3"
[defaults]
scenario = { town = "town07", placement = "standard", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 50 }
perception = { kind = "oracle" }
[[cells]]
name = "clean"
policy = { name = "baseline" }
"""


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("reproduce")
    (root / "table3_stop_positions.toml").write_text(TINY_TABLE3)
    (root / "fig3_detection.toml").write_text(TINY_FIG3)
    paths = [root / "table3_stop_positions.toml", root / "fig3_detection.toml"]
    return reproduce(root / "results", workers=1, experiment_paths=paths, progress=False, rrd="all")


def test_every_run_has_a_record_in_spec_order_and_its_own_recording(results):
    records = read_records(results / "runs.jsonl")
    assert [(r["cell"], r["seed"]) for r in records] == [
        (cell, seed) for cell in ("clean sign, baseline", "attacked sign, side_camera", "autopilot") for seed in (0, 1)
    ] + [("clean", 0)]
    assert all(r["status"] == "ok" for r in records)
    for r in records:
        assert (results / r["rrd"]).is_file()
        assert r["rrd"] == f"rrd/{r['experiment']}/{slug(r['cell'])}__seed{r['seed']}.rrd"


def test_manifest_and_a_copy_of_the_experiment_file(results):
    manifest = json.loads((results / "manifest.json").read_text())
    assert manifest["runs"] == 7 and manifest["failed"] == 0 and manifest["workers"] == 1
    assert manifest["versions"]["precision_auto"] in ("fp32", "bf16")  # what the default ran as
    assert "OpenGL" in manifest["versions"]["gl"]  # what drew the frames
    assert (results / "experiments" / "table3_stop_positions.toml").read_text() == TINY_TABLE3


def test_report_sets_the_study_beside_ours_and_links_the_figures(results):
    report = (results / "report.md").read_text()
    assert "| clean sign, baseline | 2/2 |" in report
    assert "+4.3" in report and "-10.3" in report  # the study's Table III column
    assert "| clean | 1.00 |" in report  # Fig. 3: the oracle's confidence, every frame in range
    for figure in ("speed_vs_distance.png", "stop_positions.png", "confidence_vs_distance.png"):
        assert (results / figure).stat().st_size > 10_000
        assert f"]({figure})" in report


def test_every_experiment_file_is_in_the_study_in_all_or_among_the_files_run_by_name():
    """No file is left out of `avsim reproduce --all` without a name saying why (the YOLO files, the costly settings')."""
    shipped = {p.relative_to(EXPERIMENTS_DIR).with_suffix("").as_posix() for p in EXPERIMENTS_DIR.rglob("*.toml")}
    groups = (STUDY_EXPERIMENTS, MORE_EXPERIMENTS, YOLO_EXPERIMENTS, SETTING_EXPERIMENTS)
    listed = [name for group in groups for name in group]
    assert len(listed) == len(set(listed))
    assert set(listed) == shipped - {p for p in shipped if p.startswith(("sweeps/", "leaderboards/"))}


def _without_wall(records):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in records]


def test_a_resumed_reproduction_runs_only_the_missing_runs_and_ends_as_one_never_stopped(results, tmp_path):
    full = read_records(results / "runs.jsonl")
    stopped = tmp_path / "stopped"
    shutil.copytree(results, stopped)
    # What a reproduction stopped part-way leaves: some runs in finishing order, a torn last line, no report.
    kept = [full[3], full[0], full[6], full[1], full[5]]
    (stopped / "runs.jsonl").write_text("".join(map(encode, kept)) + '{"experiment": "table3_st')
    for name in ("report.md", "manifest.json"):
        (stopped / name).unlink()
    paths = [results.parents[1] / "table3_stop_positions.toml", results.parents[1] / "fig3_detection.toml"]

    out = reproduce(tmp_path / "unused", workers=1, experiment_paths=paths, progress=False, rrd="all", resume=stopped)

    assert out == stopped and not (tmp_path / "unused").exists()
    records = read_records(stopped / "runs.jsonl")
    assert _without_wall(records) == _without_wall(full)  # the same runs, results and order as never stopped
    assert [r for r in records if r in kept] == [full[0], full[1], full[3], full[5], full[6]]  # kept, not run again
    manifest = json.loads((stopped / "manifest.json").read_text())
    assert (manifest["runs"], manifest["ran"], manifest["reused"]) == (7, 2, 5)
    assert manifest["command"].endswith(f"--resume {stopped}") and "--experiments" in manifest["command"]
    assert "| clean sign, baseline | 2/2 |" in (stopped / "report.md").read_text()


def test_a_resumed_run_whose_experiment_file_changed_runs_again(results, tmp_path):
    stopped = tmp_path / "stopped"
    shutil.copytree(results, stopped)
    changed = tmp_path / "fig3_detection.toml"
    changed.write_text(TINY_FIG3.replace("start_dist_m = 50", "start_dist_m = 45"))
    reproduce(tmp_path, workers=1, experiment_paths=[changed], progress=False, rrd="none", resume=stopped)
    manifest = json.loads((stopped / "manifest.json").read_text())
    assert (manifest["ran"], manifest["reused"]) == (1, 0)
    records = read_records(stopped / "runs.jsonl")
    # The changed file's run first; the old records of both files are kept after it.
    assert records[0]["result"]["config"]["scenario"]["start_dist_m"] == 45.0
    assert _without_wall(records[1:]) == _without_wall(read_records(results / "runs.jsonl"))


@pytest.mark.parametrize("argv, expected", [
    (["--resume", "{tmp}/nowhere"], "no runs.jsonl there"),
    (["--resume", "{tmp}", "--out", "{tmp}/results"], "not both"),
])
def test_a_bad_resume_fails_in_one_line_and_writes_nothing(tmp_path, capsys, argv, expected):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    before = sorted(tmp_path.rglob("*"))
    code = cli.main(["reproduce", "--experiments", str(experiment), *[a.format(tmp=tmp_path) for a in argv]])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and expected in err, err
    assert sorted(tmp_path.rglob("*")) == before


def _folder_of(tmp_path, *names):
    """What a reproduction of `names` leaves before its first record: the copies of its files, an empty runs.jsonl."""
    folder = tmp_path / "folder"
    (folder / "experiments").mkdir(parents=True)
    for name in names:
        (folder / "experiments" / name).write_text(TINY_TABLE3)
    (folder / "runs.jsonl").write_text("")
    return folder


def test_a_resume_that_would_add_experiment_files_to_a_folder_is_refused_before_any_run(tmp_path, capsys):
    # A folder made with --experiments, resumed without them: the whole study would start in it.
    folder = _folder_of(tmp_path, "mine.toml")
    before = sorted(tmp_path.rglob("*"))
    code = cli.main(["reproduce", "--resume", str(folder), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"--resume {folder}: that folder reproduces mine.toml (its experiments/), and this command adds " in err
    assert "table3_stop_positions.toml" in err and "--yes" in err
    assert sorted(tmp_path.rglob("*")) == before


def test_a_resume_of_the_same_files_or_fewer_needs_no_yes_and_more_files_need_it(tmp_path):
    (tmp_path / "a.toml").write_text(TINY_TABLE3)
    (tmp_path / "b.toml").write_text(TINY_TABLE3)
    a, b = (load_study([tmp_path / name]) for name in ("a.toml", "b.toml"))
    both = load_study([tmp_path / "a.toml", tmp_path / "b.toml"])
    folder = _folder_of(tmp_path, "a.toml", "b.toml")
    for experiments in (both, a, b):
        check_resumed_selection(folder, experiments, yes=False)
    with pytest.raises(ConfigError, match="adds b.toml"):
        check_resumed_selection(_folder_of(tmp_path / "x", "a.toml"), both, yes=False)
    check_resumed_selection(_folder_of(tmp_path / "y", "a.toml"), both, yes=True)
    check_resumed_selection(_folder_of(tmp_path / "z"), both, yes=False)  # a folder from before its copies: unchecked


def test_a_resume_under_another_render_setting_is_refused_before_any_run(results, tmp_path, capsys):
    # The folder's runs were drawn under the default renders; --setting textured would run every one again into it.
    stopped = tmp_path / "stopped"
    shutil.copytree(results, stopped)
    before = {p: p.read_bytes() for p in stopped.rglob("*") if p.is_file()}
    table3, fig3 = results.parents[1] / "table3_stop_positions.toml", results.parents[1] / "fig3_detection.toml"
    code = cli.main(["reproduce", "--experiments", str(table3), str(fig3), "--setting", "textured", "--workers", "1",
                     "--no-progress", "--resume", str(stopped)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "its runs were drawn with scenario.materials = 'flat' and this command's with 'textured'" in err
    assert {p: p.read_bytes() for p in stopped.rglob("*") if p.is_file()} == before
    # The setting that made it passes, and so does --yes (a file that changed the key itself).
    existing = read_records(stopped / "runs.jsonl")
    check_resumed_setting(stopped, load_study([table3, fig3]), existing, yes=False)
    check_resumed_setting(stopped, load_study([table3, fig3], setting="textured"), existing, yes=True)


def test_a_set_runs_every_cell_with_the_value_and_a_resume_must_give_the_same_set(tmp_path, capsys):
    table3 = tmp_path / "table3_stop_positions.toml"
    table3.write_text(TINY_TABLE3)
    base = ["reproduce", "--experiments", str(table3), "--quick", "--workers", "1", "--no-progress", "--rrd", "none"]

    assert cli.main([*base, "--out", str(tmp_path / "results"), "--set", "scenario.start_dist_m=45"]) == 0
    (folder,) = (tmp_path / "results").iterdir()
    records = read_records(folder / "runs.jsonl")
    assert len(records) == 3 and {r["result"]["config"]["scenario"]["start_dist_m"] for r in records} == {45.0}
    assert json.loads((folder / "set.json").read_text()) == {"set": {"scenario.start_dist_m": 45}}
    assert "--set scenario.start_dist_m=45" in json.loads((folder / "manifest.json").read_text())["command"]
    assert "(with --set scenario.start_dist_m=45)" in (folder / "report.md").read_text()
    capsys.readouterr()

    # Without the --set (or with another) every run would run again into the folder: refused, the folder untouched.
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    for other in ([], ["--set", "scenario.start_dist_m=40"]):
        assert cli.main([*base, "--resume", str(folder), *other]) == 2
        err = capsys.readouterr().err
        assert len(err.splitlines()) == 1 and "its runs were given --set scenario.start_dist_m=45" in err, err
        assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    # The same --set resumes it, and every run is already there.
    assert cli.main([*base, "--resume", str(folder), "--set", "scenario.start_dist_m=45"]) == 0
    assert json.loads((folder / "manifest.json").read_text())["ran"] == 0


@pytest.mark.parametrize("items, expected", [
    (["policy.name=baseline"], "its cells differ in policy.name"),
    (["scenario.seed=2"], "--set scenario.seed"),
    (["policy.nothing=1"], "unknown config key 'policy.nothing'"),
    (["scenario.materials=textured"], "--setting sets that key too"),
])
def test_a_bad_set_fails_in_one_line_and_writes_nothing(tmp_path, capsys, items, expected):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    before = sorted(tmp_path.rglob("*"))
    argv = [flag for item in items for flag in ("--set", item)]
    code = cli.main(["reproduce", "--experiments", str(experiment), "--out", str(tmp_path / "results"),
                     "--setting", "textured", *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and expected in err, err
    assert sorted(tmp_path.rglob("*")) == before


def test_quick_keeps_one_seed_per_cell(tmp_path):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    assert [e.seeds for e in load_study([experiment], quick=True)] == [1]


def test_more_seeds_extend_a_reproduction_whose_first_seeds_are_the_same_runs(results, tmp_path, capsys):
    full = read_records(results / "runs.jsonl")
    extended = tmp_path / "extended"
    shutil.copytree(results, extended)
    table3 = results.parents[1] / "table3_stop_positions.toml"

    code = cli.main(["reproduce", "--experiments", str(table3), "--seeds", "3", "--workers", "1", "--no-progress",
                     "--rrd", "none", "--resume", str(extended)])

    assert code == 0, capsys.readouterr().err
    manifest = json.loads((extended / "manifest.json").read_text())
    # Seeds 0 and 1 match the 2-seed runs by config hash and are kept; only seed 2 of each cell runs.
    assert (manifest["ran"], manifest["experiments"]["table3_stop_positions"]["seeds"]) == (3, 3)
    assert "--seeds 3" in manifest["command"]
    records = read_records(extended / "runs.jsonl")
    table3_runs = [(r["cell"], r["seed"]) for r in records if r["experiment"] == "table3_stop_positions"]
    assert table3_runs == [(cell, seed) for cell in ("clean sign, baseline", "attacked sign, side_camera", "autopilot")
                           for seed in (0, 1, 2)]
    assert all(r in records for r in full)  # the first seeds' records, untouched
    assert "3 seed(s) per cell" in (extended / "report.md").read_text()


@pytest.mark.parametrize("argv, expected", [
    (["--quick", "--seeds", "3"], "give one of them"),
    (["--seeds", "0"], "--seeds"),
])
def test_a_bad_seed_count_fails_in_one_line_and_writes_nothing(tmp_path, capsys, argv, expected):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    before = sorted(tmp_path.rglob("*"))
    code = cli.main(["reproduce", "--experiments", str(experiment), "--out", str(tmp_path / "results"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and expected in err, err
    assert sorted(tmp_path.rglob("*")) == before


def test_a_bad_experiment_file_fails_in_one_line_before_anything_is_written(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY_TABLE3.replace('town = "town07"', 'town = "town99"'))
    code = cli.main(["reproduce", "--experiments", str(bad), "--out", str(tmp_path / "results")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "town99" in err
    assert not (tmp_path / "results").exists()


def test_findings_name_a_defence_that_ran_past_and_the_deceleration_it_needed(tmp_path):
    from avsim.experiments.reproduce_report import Cells, findings
    from avsim.experiments.spec import load_experiment

    path = tmp_path / "table3_stop_positions.toml"
    path.write_text(TINY_TABLE3)
    experiment = load_experiment(path)
    config = experiment.cells[1].config.to_dict()
    ran_past = {"outcome": "ran_past_sign", "speed_at_brake_mps": 20.0, "dist_at_brake_m": 20.0, "config": config}
    stopped = {"outcome": "stopped_before_line", "speed_at_brake_mps": 20.0, "dist_at_brake_m": 40.0, "config": config}
    records = [{"experiment": "table3_stop_positions", "cell": "attacked sign, side_camera", "seed": k, "status": "ok",
                "result": result, "trace": {}} for k, result in enumerate((ran_past, stopped))]
    lines = findings(Cells(records), [experiment])
    assert any("attacked sign, side_camera (defence): ran past the sign in 1 of 2 finished runs" in line and "10.0 m/s²" in line
               for line in lines)  # v²/2d = 400/40
    # Beside it, the car's full brake at that run's road friction and speed, measured, not a constant.
    from avsim.vehicle.brake_test import full_brake_decel_mps2

    measured = full_brake_decel_mps2(experiment.cells[1].config.vehicle, 0.9, 40 / 3.6)
    assert any(f"against {measured:.1f} m/s² at full brake (measured, road friction 0.9)" in line for line in lines)


def test_findings_do_not_count_a_run_that_had_no_stop_to_make_as_a_failure(tmp_path):
    from avsim.experiments.reproduce_report import Cells, findings
    from avsim.experiments.spec import load_experiment

    path = tmp_path / "table3_stop_positions.toml"
    path.write_text(TINY_TABLE3)
    experiment = load_experiment(path)
    drove_through = {"outcome": "drove_through", "stop_required": False, "speed_at_brake_mps": None,
                     "dist_at_brake_m": None, "config": experiment.cells[1].config.to_dict()}
    records = [{"experiment": "table3_stop_positions", "cell": "attacked sign, side_camera", "seed": 0, "status": "ok",
                "result": drove_through, "trace": {}}]
    assert not any("attacked sign, side_camera" in line for line in findings(Cells(records), [experiment]))


def test_a_compare_report_sets_each_cell_beside_the_other_experiments_same_named_cell(tmp_path):
    from avsim.experiments.report_cells import Cells
    from avsim.experiments.report_sections import compare_section
    from avsim.experiments.spec import load_experiment

    (tmp_path / "dry.toml").write_text(TINY_TABLE3)
    (tmp_path / "wet.toml").write_text(TINY_TABLE3.replace('report = "table3"', 'report = "compare"\ncompare_with = "dry"')
                                       .replace("start_dist_m = 50 }", "start_dist_m = 50, road_friction = 0.5 }"))
    dry, wet = load_experiment(tmp_path / "dry.toml"), load_experiment(tmp_path / "wet.toml")
    records = [{"experiment": exp.name, "cell": "autopilot", "seed": 0, "status": "ok", "trace": {},
                "result": {"outcome": "stopped_before_line", "sign_margin_m": margin, "dist_at_brake_m": 30.0,
                           "config": exp.cell("autopilot").config.to_dict()}}
               for exp, margin in ((dry, 1.5), (wet, -2.0))]
    lines = compare_section(Cells(records), wet, dry)
    row = next(line for line in lines if line.startswith("| autopilot |"))
    cols = [c.strip() for c in row.strip("|").split("|")]
    assert cols[1:3] == ["1/1", "1.5"] and cols[5:7] == ["1/1", "-2.0"]
    assert float(cols[8]) < 0.7 * float(cols[4])  # wet road (mu 0.5 against 0.9): far less full-brake deceleration
    assert compare_section(Cells(records), wet, None)[0].startswith("(Run `experiments/dry.toml`")


def test_zero_workers_is_refused_before_a_results_folder_is_made(tmp_path, capsys):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    code = cli.main(["reproduce", "--experiments", str(experiment), "--workers", "0", "--out", str(tmp_path / "results")])
    assert code == 2 and "--workers" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize("sign, mention", [("nosuchtexture", "unknown sign texture 'nosuchtexture'"),
                                           ("FAKE_PNG", "fake.png")])
def test_a_missing_or_broken_sign_texture_is_refused_before_a_results_folder_is_made(tmp_path, capsys, sign, mention):
    (tmp_path / "fake.png").write_text("not a png")
    sign = str(tmp_path / "fake.png") if sign == "FAKE_PNG" else sign
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3.replace('town = "town07",', f'town = "town07", sign = "{sign}",'))
    code = cli.main(["reproduce", "--experiments", str(experiment), "--workers", "1", "--no-progress",
                     "--out", str(tmp_path / "results")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"{experiment}: cell " in err and "scenario.sign" in err and mention in err
    assert not (tmp_path / "results").exists()


def test_reproduce_on_a_dead_ray_address_is_refused_before_a_results_folder_is_made(tmp_path, capsys):
    pytest.importorskip("ray")
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    code = cli.main(["reproduce", "--experiments", str(experiment), "--backend", "ray", "--address", "127.0.0.1:1",
                     "--out", str(tmp_path / "results")])
    assert code == 2 and "no Ray cluster answers" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


def test_a_reproduce_where_every_run_failed_says_so_and_exits_non_zero(tmp_path, capsys, monkeypatch):
    import avsim.loop
    from avsim.errors import RenderError

    def no_scene(config):
        raise RenderError("the GL went away")  # as a run that fails on the machine, after every input was checked

    monkeypatch.setattr(avsim.loop, "build_scene", no_scene)  # the runs run in this process (--workers 1)
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text(TINY_TABLE3)
    code = cli.main(["reproduce", "--experiments", str(experiment), "--workers", "1", "--no-progress",
                     "--out", str(tmp_path / "results")])
    err = capsys.readouterr().err
    assert code == 1 and len(err.splitlines()) == 1 and "every one of the 6 runs failed" in err, err
    report = next((tmp_path / "results").glob("*/report.md")).read_text()
    assert "**Every run failed** (6 of 6)" in report
    assert "no run finished, so there is no outcome to report" in report
    assert "every finished defended run stopped" not in report and "every defended run stopped" not in report
    assert "| clean sign, baseline | 0/0 (2 failed) |" in report


def test_failed_runs_are_counted_beside_the_outcomes_of_the_others(tmp_path):
    from avsim.experiments.reproduce_report import Cells, findings
    from avsim.experiments.spec import load_experiment

    path = tmp_path / "table3_stop_positions.toml"
    path.write_text(TINY_TABLE3)
    experiment = load_experiment(path)
    stopped = {"outcome": "stopped_before_line", "speed_at_brake_mps": 20.0, "dist_at_brake_m": 40.0}
    cell = "attacked sign, side_camera"
    records = [{"experiment": "table3_stop_positions", "cell": cell, "seed": 0, "status": "ok", "result": stopped, "trace": {}},
               {"experiment": "table3_stop_positions", "cell": cell, "seed": 1, "status": "failed", "result": None,
                "trace": None, "error": "RenderError: x"}]
    cells = Cells(records)
    assert cells.stopped("table3_stop_positions", cell) == "1/1 (1 failed)"
    text = "\n".join(findings(cells, [experiment]))
    assert "the failed runs below have no outcome" in text and f"{cell} (1 of 2)" in text


def test_a_sensitivity_report_tabulates_each_varied_constant_with_the_others_at_their_defaults(tmp_path):
    from avsim.experiments.report_cells import Cells
    from avsim.experiments.report_sections import sensitivity_section
    from avsim.experiments.spec import load_experiment

    cells_toml = "".join(f'[[cells]]\nname = "{name}"\npolicy = {{ name = "baseline", {setting} }}\n'
                         for name, setting in (("gate 30", "trigger_dist_m = 30"), ("gate 40", "trigger_dist_m = 40"),
                                               ("no gate", "trigger_dist_m = inf"), ("conf 0.7", "conf_threshold = 0.7")))
    (tmp_path / "s.toml").write_text('report = "sensitivity"\nseeds = 2\n' + cells_toml)
    experiment = load_experiment(tmp_path / "s.toml")
    outcomes = {"gate 30": ("ran_past_sign", "ran_past_sign"), "gate 40": ("stopped_before_line",) * 2,
                "no gate": ("stopped_before_line",) * 2, "conf 0.7": ("stopped_before_line", "ran_past_sign")}
    records = [{"experiment": "s", "cell": name, "seed": k, "status": "ok", "trace": {},
                "result": {"outcome": outcome, "sign_margin_m": 1.0 if outcome == "stopped_before_line" else -3.0}}
               for name, pair in outcomes.items() for k, outcome in enumerate(pair)]
    text = "\n".join(sensitivity_section(Cells(records), experiment, {}))
    assert "| policy | sign | policy.trigger_dist_m = 30 | policy.trigger_dist_m = 40 | policy.trigger_dist_m = none |" in text
    assert "| baseline | clean | 0/2 (0.00–0.66), -3.0 ± 0.0 m | 2/2 (0.34–1.00), 1.0 ± 0.0 m | 2/2 (0.34–1.00), 1.0 ± 0.0 m |" in text
    # The threshold table holds the gate at its default (40 m): the gate-30 and no-gate cells stay out of it.
    assert "| baseline | clean | 2/2 (0.34–1.00), 1.0 ± 0.0 m | 1/2 (0.09–0.91), -1.0 ± 2.8 m |" in text


def _stop_rate_rows(lines: list[str]) -> dict[str, list[str]]:
    """A stop-rates table's body as {town and placement: its cells, one a policy}."""
    return {line.split("|")[1].strip(): [c.strip() for c in line.strip("|").split("|")[1:]]
            for line in lines if line.startswith("| ") and "placement" not in line}


def test_a_stop_rates_report_gives_each_policy_and_place_its_rate_interval_and_margin(tmp_path):
    from avsim.experiments.report_cells import Cells
    from avsim.experiments.report_sections import stop_rates
    from avsim.experiments.spec import load_experiment

    path = tmp_path / "rates.toml"
    path.write_text("""
report = "stop_rates"
[defaults]
perception = { kind = "oracle" }
[[cells]]
name = "a, baseline"
scenario = { town = "town07", placement = "near" }
[[cells]]
name = "a, adjusted"
scenario = { town = "town07", placement = "near" }
policy = { name = "adjusted" }
[[cells]]
name = "b, baseline"
scenario = { town = "town10", placement = "far" }
""")
    experiment = load_experiment(path)
    outcomes = {"a, baseline": [("stopped_before_line", 3.0), ("ran_past_sign", -1.0)],
                "a, adjusted": [("stopped_past_line", 0.5)], "b, baseline": [("never_braked", -40.0)]}
    records = [{"experiment": "rates", "cell": cell, "seed": k, "status": "ok", "trace": {},
                "result": {"outcome": outcome, "sign_margin_m": margin}}
               for cell, runs in outcomes.items() for k, (outcome, margin) in enumerate(runs)]
    records.append({"experiment": "rates", "cell": "b, baseline", "seed": 1, "status": "failed", "result": None,
                    "trace": None, "error": "RenderError: x"})
    rows = _stop_rate_rows(stop_rates(Cells(records), experiment))
    assert rows["town07 near"] == ["1/2 (0.09–0.91); 1.0 ± 2.8 m", "1/1 (0.21–1.00); 0.5 m"]
    assert rows["town10 far"] == ["0/1 (0.00–0.79); -40.0 m; 1 failed", "–"]
    assert rows["all cells"] == ["1/3 (0.06–0.79); -12.7 ± 23.8 m", "1/1 (0.21–1.00); 0.5 m"]


def test_stops_that_ended_beyond_the_braking_gate_are_counted_beside_the_stop_rate_and_named_in_the_findings(tmp_path):
    from avsim.experiments.report_cells import Cells
    from avsim.experiments.report_sections import stop_rates
    from avsim.experiments.reproduce_report import findings
    from avsim.experiments.spec import load_experiment

    path = tmp_path / "rates.toml"
    path.write_text("""
report = "stop_rates"
[defaults]
perception = { kind = "oracle" }
scenario = { town = "town10", placement = "standard" }
[[cells]]
name = "gate"
[[cells]]
name = "no gate"
scenario = { placement = "far" }
policy = { trigger_dist_m = inf }
""")
    experiment = load_experiment(path)
    # (outcome, bumper to line at rest, bumper to sign at rest, braking began before the sign) [m]
    runs = {"gate": [("stopped_before_line", 7.3, 17.0, 42.6), ("stopped_before_line", 98.2, 108.0, 133.2),
                     ("stopped_before_line", 102.4, 112.2, 137.5)],
            "no gate": [("stopped_before_line", 98.2, 108.0, 133.2)]}
    records = [{"experiment": "rates", "cell": cell, "seed": k, "status": "ok", "trace": {},
                "result": {"outcome": outcome, "margin_m": margin, "sign_margin_m": sign_margin, "dist_at_brake_m": brake,
                           "speed_at_brake_mps": 23.5, "stop_required": True,
                           "config": experiment.cell(cell).config.to_dict()}}
               for cell, cell_runs in runs.items() for k, (outcome, margin, sign_margin, brake) in enumerate(cell_runs)]
    rows = _stop_rate_rows(stop_rates(Cells(records), experiment))
    # Still counted as stops, as in the study; the count beside says how many began braking outside the gate.
    assert rows["town10 standard"] == ["3/3 (0.44–1.00); 79.1 ± 53.8 m; 2 at rest beyond the gate"]
    assert rows["town10 far"] == ["1/1 (0.21–1.00); 108.0 m"]  # no gate: nothing to be beyond
    assert rows["all cells"] == ["4/4 (0.51–1.00); 86.3 ± 46.2 m; 2 at rest beyond the gate"]
    lines = findings(Cells(records), [experiment])
    named = [line for line in lines if line.startswith("- ") and "beyond the" in line]
    assert len(named) == 1 and named[0].endswith(
        "/ gate: 2 of 3 finished runs came to rest 98.2–102.4 m before the stop line, beyond the 40 m gate; "
        "braking began 133.2–137.5 m before the sign.")
