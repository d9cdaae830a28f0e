"""`avsim sweep`: grid files expand in a fixed order, bad files fail in one line, the smoke sweep runs end to end."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from avsim import cli
from avsim.cli.overrides import parse_set
from avsim.config import SimConfig
from avsim.errors import ConfigError
from avsim.experiments.render_setting import sweep_under_setting
from avsim.experiments.results_file import read_records
from avsim.experiments.sweep import FOLDER_FILES, load_sweep
from avsim.experiments.sweep_report import front_measures, ordered_by_strength, run_cell_text, safety_map, sign_strength
from avsim.realism.settings import SETTINGS

SWEEPS_DIR = Path(__file__).resolve().parents[2] / "experiments" / "sweeps"
SMOKE = SWEEPS_DIR / "sweep_smoke.toml"


def _write(tmp_path: Path, text: str, name: str = "grid.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


# ---- the shipped files ----------------------------------------------------------------------

def test_the_speed_sweep_is_speeds_times_signs_times_the_four_perception_policies():
    sweep = load_sweep(SWEEPS_DIR / "speed_sweep.toml")
    grid = dict(sweep.grid)
    assert [key for key, _ in sweep.grid] == ["policy.name", "scenario.sign", "scenario.speed_kmh"]
    assert grid["policy.name"] == ("baseline", "adjusted", "side_camera", "combined")
    assert grid["scenario.sign"][0] == "clean" and len(grid["scenario.sign"]) >= 3
    speeds = grid["scenario.speed_kmh"]
    assert speeds[0] == 30.0 and speeds[-1] == 120.0 and list(speeds) == sorted(speeds) and 7 <= len(speeds) <= 10
    assert sweep.base.perception.kind == "detector" and sweep.seeds == 1
    assert len(sweep.runs()) == 4 * len(grid["scenario.sign"]) * len(speeds)
    # Every attacked texture carries its budget, so the safety map can place it on the strength axis.
    strengths = [sign_strength(sign) for sign in grid["scenario.sign"]]
    assert all(s.budget is not None for s in strengths)
    assert [s.budget for s in ordered_by_strength(strengths)] == sorted(s.budget for s in strengths)


def test_the_smoke_sweep_is_four_short_oracle_runs():
    sweep = load_sweep(SMOKE)
    assert [(r.point["scenario.speed_kmh"], r.point["policy.name"]) for r in sweep.runs()] == [
        (40.0, "baseline"), (40.0, "side_camera"), (60.0, "baseline"), (60.0, "side_camera")]
    assert sweep.base.perception.kind == "oracle" and sweep.base.scenario.start_dist_m == 60.0


# ---- expansion ------------------------------------------------------------------------------

def test_grid_expands_to_the_cartesian_product_times_seeds_first_key_slowest(tmp_path):
    sweep = load_sweep(_write(tmp_path, """
        title = "t"
        seeds = 2
        [defaults]
        scenario = { town = "town03", placement = "far" }
        [grid]
        "scenario.speed_kmh" = [30, 60]
        "policy.name" = ["baseline", "adjusted", "combined"]
    """))
    runs = sweep.runs()
    assert len(runs) == 2 * 3 * 2
    assert [(r.point["scenario.speed_kmh"], r.point["policy.name"], r.seed) for r in runs] == [
        (speed, policy, seed) for speed in (30.0, 60.0) for policy in ("baseline", "adjusted", "combined")
        for seed in (0, 1)]
    for run in runs:
        assert run.config.scenario.speed_kmh == run.point["scenario.speed_kmh"]
        assert run.config.policy.name == run.point["policy.name"]
        assert run.config.scenario.seed == run.seed
        assert (run.config.scenario.town, run.config.scenario.placement) == ("town03", "far")
    assert runs == load_sweep(sweep.path).runs()  # deterministic
    specs = sweep.specs()
    assert len({s.spec_hash for s in specs}) == len(specs)
    assert specs[0].experiment == "grid" and specs[0].cell == "scenario.speed_kmh=30.0, policy.name=baseline"


def test_a_toml_dotted_grid_key_is_the_same_as_a_quoted_one(tmp_path):
    quoted = load_sweep(_write(tmp_path, '[grid]\n"scenario.speed_kmh" = [30, 60]\n', "a.toml"))
    dotted = load_sweep(_write(tmp_path, '[grid]\nscenario.speed_kmh = [30, 60]\n', "b.toml"))
    assert quoted.grid == dotted.grid == (("scenario.speed_kmh", (30.0, 60.0)),)


def test_a_grid_may_take_the_junction_without_a_stop_sign(tmp_path):
    sweep = load_sweep(_write(tmp_path, '[grid]\n"scenario.sign" = ["clean", "none"]\n'))
    assert [run.config.scenario.stop_required for run in sweep.runs()] == [True, False]


# ---- bad files: one line naming the file and the key -----------------------------------------

@pytest.mark.parametrize("text, expected", [
    ('colour = "red"\n[grid]\n"scenario.speed_kmh" = [30]\n', "unknown top-level key 'colour'"),
    ('[grid]\n"scenario.sped_kmh" = [30]\n', "unknown config key 'scenario.sped_kmh'"),
    ('[defaults]\nscenario = { twon = "town03" }\n[grid]\n"scenario.speed_kmh" = [30]\n', "unknown config key 'scenario.twon'"),
    ('[grid]\n"scenario.speed_kmh" = []\n', "'scenario.speed_kmh' is an empty list"),
    ('[grid]\n"scenario.speed_kmh" = [30, "fast"]\n', "config key 'scenario.speed_kmh' must be float, got 'fast'"),
    ('[grid]\n"scenario.speed_kmh" = 30\n', "'scenario.speed_kmh' must be a list of values"),
    ('[grid]\n"scenario.speed_kmh" = [30, 250]\n', "scenario.speed_kmh must be in (0, 200]"),
    ('[grid]\n"scenario.speed_kmh" = [30, 30.0]\n', "'scenario.speed_kmh' lists the value 30.0 twice"),
    ('[grid]\n"policy.name" = ["baseline", "brake_harder"]\n', "policy.name: unknown policy 'brake_harder'"),
    ('[grid]\n"scenario.town" = ["town99"]\n', "scenario.town: unknown town 'town99'"),
    ('[grid]\n"scenario.sign" = ["clean", "yang_eps9"]\n', "scenario.sign: unknown sign texture 'yang_eps9'"),
    ('[grid]\n"scenario.sign" = ["no/such.png"]\n', "scenario.sign: texture no/such.png does not exist"),
    ('[grid]\n"scenario.seed" = [0, 1]\n', "'scenario.seed' cannot be a grid key"),
    ('[grid]\n"scenario" = [{ speed_kmh = 30 }]\n', "'scenario' values must be numbers, strings or booleans"),
    ('seeds = 0\n[grid]\n"scenario.speed_kmh" = [30]\n', "'seeds' must be an integer >= 1"),
    ('title = "no grid"\n', "no [grid] table"),
    # Each value is fine alone; together they break a limit that ties two keys.
    ('[grid]\n"scenario.fog_start_m" = [10]\n"scenario.fog_end_m" = [5]\n', "scenario.fog_start_m must be >= 0 and below fog_end_m"),
])
def test_a_bad_sweep_file_is_one_line_naming_the_file_and_key(tmp_path, text, expected):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_sweep(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert expected in message


def test_the_cli_rejects_a_bad_file_with_exit_2_and_writes_nothing(tmp_path, capsys):
    path = _write(tmp_path, '[grid]\n"policy.name" = ["baseline", "bogus"]\n')
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("avsim: error: ") and "\n" not in err and "policy.name" in err and "bogus" in err
    assert not out.exists()


# ---- --set KEY=VALUE over a sweep file (`avsim.experiments.set_overrides`) ---------------------
def test_a_sweep_under_a_set_is_the_sweep_of_the_file_with_the_key_in_defaults(tmp_path):
    by_hand = tmp_path / "by_hand.toml"
    by_hand.write_text(SMOKE.read_text().replace("start_dist_m = 60", "start_dist_m = 45"))
    with_set = load_sweep(SMOKE, overrides=parse_set(["scenario.start_dist_m=45"]))
    assert [run.config for run in with_set.runs()] == [run.config for run in load_sweep(by_hand).runs()]
    assert with_set.set_items == (("scenario.start_dist_m", 45),)
    assert with_set.title.endswith("(with --set scenario.start_dist_m=45)")


@pytest.mark.parametrize("items, expected", [
    (["scenario.speed_kmh=50"], "its [grid] sets scenario.speed_kmh itself, and its runs would take that over --set"),
    (["perception.coco_input=upscale"], "--set: perception.coco_input is read only by"),
    (["scenario.seed=1"], "--set scenario.seed"),
    (["scenario.town=nowhere"], "--set: "),
])
def test_a_set_a_sweeps_grid_would_override_or_no_run_reads_is_refused(items, expected):
    with pytest.raises(ConfigError) as refused:
        load_sweep(SMOKE, overrides=parse_set(items))
    assert expected in str(refused.value) and "\n" not in str(refused.value), str(refused.value)


def test_a_set_of_a_key_the_sweeps_setting_sets_is_refused():
    sweep = load_sweep(SMOKE, overrides=parse_set(["scenario.materials=flat"]))
    with pytest.raises(ConfigError, match="--set sets scenario.materials, which --setting textured sets too"):
        sweep_under_setting(sweep, SETTINGS["textured"])




# ---- the smoke sweep, end to end -------------------------------------------------------------

@pytest.fixture(scope="module")
def smoke_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "smoke"
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    return out


def test_the_smoke_sweep_writes_one_ok_record_per_run_in_grid_order(smoke_out):
    records = read_records(smoke_out / "results.jsonl")
    assert [r["status"] for r in records] == ["ok"] * 4
    assert [r["point"] for r in records] == [
        {"scenario.speed_kmh": speed, "policy.name": policy} for speed in (40.0, 60.0) for policy in ("baseline", "side_camera")]
    for record in records:
        config = record["result"]["config"]
        assert config["scenario"]["speed_kmh"] == record["point"]["scenario.speed_kmh"]
        assert config["policy"]["name"] == record["point"]["policy.name"]
        assert record["experiment"] == "sweep_smoke" and record["rrd"] is None
    # The oracle sees the sign from the start: every run stops well before it.
    assert all(r["result"]["outcome"] == "stopped_before_line" for r in records)


def test_the_smoke_sweep_writes_the_summary_figure_and_manifest(smoke_out):
    summary = (smoke_out / "summary.md").read_text()
    assert "| baseline | 60 |" in summary and "| side_camera | 60 |" in summary
    assert (smoke_out / "safety_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    manifest = json.loads((smoke_out / "manifest.json").read_text())
    assert (manifest["runs"], manifest["ran"], manifest["failed"], manifest["workers"]) == (4, 4, 0, 1)
    assert (smoke_out / "sweep.toml").read_text() == SMOKE.read_text()


def test_every_file_the_smoke_sweep_writes_is_one_it_checks_before_its_first_run(smoke_out):
    # FOLDER_FILES is checked before the first run (a folder in a report file's place); a file missing from it
    # would be found only after the last run.
    assert {p.name for p in smoke_out.iterdir() if p.is_file()} <= set(FOLDER_FILES)
    assert {p.name for p in smoke_out.iterdir() if p.is_dir()} <= {"rrd", "mcap"}  # `recording_folders`' own


def test_a_second_sweep_into_the_same_folder_needs_resume_which_reuses_the_ok_runs(smoke_out, capsys):
    before = (smoke_out / "results.jsonl").read_text()
    assert cli.main(["sweep", str(SMOKE), "--out", str(smoke_out), "--no-progress"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert cli.main(["sweep", str(SMOKE), "--out", str(smoke_out), "--resume", "--no-progress"]) == 0
    manifest = json.loads((smoke_out / "manifest.json").read_text())
    assert (manifest["ran"], manifest["reused"]) == (0, 4)
    assert (smoke_out / "results.jsonl").read_text() == before


@pytest.mark.slow  # end to end, about 15-20 CPU-s: the slow pass, so the default run stays under its 10 minutes
def test_a_sweep_with_set_runs_every_point_with_the_value_and_a_resume_must_give_it_again(tmp_path, capsys):
    out = tmp_path / "smoke_45"
    base = ["sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--no-progress"]
    assert cli.main([*base, "--set", "scenario.start_dist_m=45"]) == 0
    records = read_records(out / "results.jsonl")
    assert [r["result"]["config"]["scenario"]["start_dist_m"] for r in records] == [45.0] * 4
    assert json.loads((out / "set.json").read_text()) == {"set": {"scenario.start_dist_m": 45}}
    assert "--set scenario.start_dist_m=45" in json.loads((out / "manifest.json").read_text())["command"]
    assert "(with --set scenario.start_dist_m=45)" in (out / "summary.md").read_text()
    capsys.readouterr()
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert cli.main([*base, "--resume"]) == 2  # every run would run again, beside the first ones
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "its runs were given --set scenario.start_dist_m=45" in err, err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert cli.main([*base, "--resume", "--set", "scenario.start_dist_m=45"]) == 0
    assert json.loads((out / "manifest.json").read_text())["ran"] == 0


def test_a_resume_under_another_setting_than_the_folders_is_refused_before_anything_runs(smoke_out, capsys):
    before = {p: p.read_bytes() for p in smoke_out.rglob("*") if p.is_file()}
    assert cli.main(["sweep", str(SMOKE), "--out", str(smoke_out), "--workers", "1", "--no-progress", "--resume",
                     "--setting", "sheeting"]) == 2  # made under the default renders: every run would run again
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "rendered under --setting baseline and this avsim sweep under --setting sheeting" in err, err
    assert {p: p.read_bytes() for p in smoke_out.rglob("*") if p.is_file()} == before


@pytest.mark.slow  # end to end, about 15-20 CPU-s: the slow pass, so the default run stays under its 10 minutes
def test_a_run_that_raises_is_a_failed_record_counted_in_the_summary_and_run_again_on_resume(smoke_out, tmp_path,
                                                                                              monkeypatch):
    from avsim.experiments import run_task

    real = run_task.run_recorded

    def renderer_lost_at_60(config, **kwargs):
        if config.scenario.speed_kmh == 60.0:
            raise RuntimeError("EGL context lost")
        return real(config, **kwargs)

    # --workers 1 runs in this process, and --batch 1 one run at a time, through run_recorded. The two runs at
    # 40 km/h are the smoke sweep's own, finished: the folder is one that a first, interrupted sweep left.
    monkeypatch.setattr(run_task, "run_recorded", renderer_lost_at_60)
    out = tmp_path / "failing"
    out.mkdir()
    finished = [line for line in (smoke_out / "results.jsonl").read_text().splitlines()
                if json.loads(line)["result"]["config"]["scenario"]["speed_kmh"] == 40.0]
    (out / "results.jsonl").write_text("".join(line + "\n" for line in finished))
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--batch", "1", "--no-progress",
                     "--resume"]) == 0
    records = read_records(out / "results.jsonl")
    assert [r["status"] for r in records] == ["ok", "ok", "failed", "failed"]
    for record in records[2:]:
        assert record["error"].startswith("RuntimeError: EGL context lost (at test_sweep.py:")
        assert record["result"] is None and record["trace"] is None
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["runs"], manifest["failed"]) == (4, 2)
    summary = (out / "summary.md").read_text()
    assert "4 runs (2 failed)" in summary and "## Failed runs (2)" in summary
    assert "- scenario.speed_kmh=60.0, policy.name=baseline, seed 0: RuntimeError: EGL context lost" in summary
    assert "| baseline | 40 |" in summary  # a failed speed is not known to be safe

    monkeypatch.undo()
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--resume", "--no-progress"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert (manifest["ran"], manifest["reused"], manifest["failed"]) == (2, 2, 0)
    strip = lambda rs: [{k: v for k, v in r.items() if k != "wall_s"} for r in rs]  # noqa: E731
    assert strip(read_records(out / "results.jsonl")) == strip(read_records(smoke_out / "results.jsonl"))


# ---- the safety map, on synthetic records ----------------------------------------------------

def _record(policy: str, sign: str, speed: float, outcome: str | None, seed: int = 0, margin: float = 1.0) -> dict:
    point = {"scenario.speed_kmh": speed, "scenario.sign": sign, "policy.name": policy}
    if outcome is None:
        return {"point": point, "seed": seed, "status": "failed", "result": None, "error": "RenderError: x"}
    return {"point": point, "seed": seed, "status": "ok", "result": {"outcome": outcome, "sign_margin_m": margin}}


def test_safety_map_is_the_highest_speed_at_which_every_run_stopped_before_the_sign():
    line, sign, past, none = "stopped_before_line", "stopped_past_line", "ran_past_sign", "never_braked"
    records = [
        # baseline, clean: safe at 30 and 60 (one seed stopped between line and sign), not at 90.
        _record("baseline", "clean", 30, line), _record("baseline", "clean", 30, line, seed=1),
        _record("baseline", "clean", 60, line), _record("baseline", "clean", 60, sign, seed=1),
        _record("baseline", "clean", 90, line), _record("baseline", "clean", 90, past, seed=1, margin=-2.0),
        # baseline, yang: nothing is safe.
        *(_record("baseline", "yang", s, none, seed=k, margin=-50.0) for s in (30, 60, 90) for k in (0, 1)),
        # side_camera, yang: a failed run at 30 and a miss at 60, yet both seeds stop at 90.
        _record("side_camera", "yang", 30, None), _record("side_camera", "yang", 30, line, seed=1),
        _record("side_camera", "yang", 60, line), _record("side_camera", "yang", 60, none, seed=1),
        _record("side_camera", "yang", 90, line), _record("side_camera", "yang", 90, line, seed=1),
    ]
    smap = safety_map(records, SimConfig())
    assert smap.speeds_kmh == (30.0, 60.0, 90.0)
    assert smap.policies == ("baseline", "side_camera") and smap.signs == ("clean", "yang")
    assert smap.max_safe_kmh("baseline", "clean") == 60.0 == smap.safe_up_to_kmh("baseline", "clean")
    assert smap.max_safe_kmh("baseline", "yang") is None and smap.safe_up_to_kmh("baseline", "yang") is None
    assert smap.max_safe_kmh("side_camera", "yang") == 90.0  # the highest safe speed ...
    assert smap.safe_up_to_kmh("side_camera", "yang") is None  # ... above speeds that were not safe
    assert smap.max_safe_kmh("side_camera", "clean") is None  # never run: not known to be safe
    cell = smap.cells[("side_camera", "yang", 30.0)]
    assert (cell.runs, cell.stopped, cell.failed, cell.safe) == (2, 1, 1, False)
    assert smap.cells[("baseline", "clean", 90.0)].sign_margins_m == (1.0, -2.0)


def test_a_stop_beyond_the_braking_gate_is_counted_in_its_speed_cell_and_is_still_a_stop():
    gate_40 = {"policy": {"trigger_dist_m": 40.0}}
    records = [_record("baseline", "clean", 85, "stopped_before_line", seed=k, margin=margin + 1.0) for k, margin in
               enumerate((98.2, 7.3))]
    for record, margin in zip(records, (98.2, 7.3)):
        record["result"] |= {"margin_m": margin, "stop_required": True, "config": gate_40}
    cell = safety_map(records, SimConfig()).cells[("baseline", "clean", 85.0)]
    assert (cell.stopped, cell.beyond_gate, cell.safe) == (2, 1, True)
    assert run_cell_text(cell) == "2/2; 1 beyond the gate"


def test_safety_map_takes_keys_the_grid_does_not_vary_from_the_base_config():
    records = [{"point": {"scenario.speed_kmh": 50.0}, "seed": 0, "status": "ok",
                "result": {"outcome": "stopped_before_line", "sign_margin_m": 3.0}}]
    base = SimConfig()
    smap = safety_map(records, base)
    assert smap.max_safe_kmh(base.policy.name, base.scenario.sign) == 50.0


def test_sign_strength_reads_the_budget_from_the_texture_record():
    assert sign_strength("clean").budget == 0.0
    yang = sign_strength("yang")
    assert (yang.method, yang.budget_key, yang.budget, yang.label) == ("yang", "eps_peak", 0.27, "yang eps_peak=0.27")


def test_front_measures_are_the_peak_confidence_and_the_distance_of_the_first_confident_frame():
    def record(sign, conf, status="ok"):
        point = {"scenario.sign": sign}
        if status != "ok":
            return {"point": point, "status": status, "result": None, "trace": None}
        result = {"config": {"policy": {"conf_threshold": 0.5}}}
        return {"point": point, "status": "ok", "result": result,
                "trace": {"sign_dist_m": [40.0, 35.0, 30.0, 25.0], "front_conf": conf}}

    measures = front_measures([record("clean", [0.2, 0.6, 0.9, 0.8]), record("clean", [0.5, 0.7, 0.7, 0.7]),
                               record("yang", [0.1, 0.3, 0.4, 0.2]), record("yang", [0.1, 0.2, 0.6, 0.3]),
                               record("yang", None, status="failed")], SimConfig())
    clean, yang = measures["clean"], measures["yang"]
    assert (clean.runs, clean.reached) == (2, 2)
    assert clean.peak_conf == pytest.approx(0.8) and clean.range_m == pytest.approx(37.5)  # 35 m and 40 m
    assert (yang.runs, yang.reached) == (2, 1)  # the failed run has no trace
    assert yang.peak_conf == pytest.approx(0.5) and yang.range_m == pytest.approx(30.0)
