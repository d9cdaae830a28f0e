"""`avsim leaderboard`: the shipped file's matrix, the file format's checks, and a small board run
end to end (oracle perception, short approaches) through the resumable sweep machinery."""

import json
import shutil
from pathlib import Path

import pytest

from avsim.cli import main
from avsim.cli.overrides import parse_set
from avsim.errors import ConfigError
from avsim.experiments.leaderboard import AVAILABILITY, DEFAULT_FILE, SAFETY, load_leaderboard, unique_specs
from avsim.experiments.leaderboard_run import run_leaderboard
from avsim.experiments.leaderboard_report import Results, condition_table, pareto_front, rows
from avsim.experiments.run_task import config_hash
from avsim.experiments.results_file import read_records

NEW_DEFENCES = ("temporal_vote", "map_prior", "ensemble_or", "ensemble_and", "purify_jpeg", "purify_median")
STUDY_ROWS = ("adjusted", "side_camera", "combined", "study_stack")

TINY = """
title = "tiny"
[defaults]
scenario = { town = "town07", placement = "standard", speed_kmh = 85, start_speed_kmh = 85, start_dist_m = 70 }
perception = { kind = "oracle" }
[vary]
scenario = { sun_elevation_deg = [30, 70] }
[conditions.clean]
scenario = { sign = "clean" }
[conditions.strongest]
note = "stand-in"
scenario = { sign = "yang" }
[[defences]]
name = "baseline"
policy = { name = "baseline" }
adaptive = { scenario = { sign = "yang" } }
adaptive_note = "placeholder"
[[defences]]
name = "map_prior"
policy = { name = "map_prior" }
adaptive = { scenario = { sign = "yang", map_error = "missing_stop" } }
[[places]]
town = "town07"
placement = "standard"
seeds = 2
quick_seeds = 1
[[availability]]
name = "no stop sign"
scenario = { sign = "none" }
seeds = 1
quick_seeds = 1
[[availability]]
name = "mapped stop absent"
scenario = { sign = "none", map_error = "phantom_stop" }
seeds = 1
defences = ["map_prior"]
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "board.toml"
    path.write_text(text)
    return path


# ---- the shipped leaderboard ---------------------------------------------------------------------

def test_the_shipped_board_has_every_defence_and_the_study_rows_and_checks_every_run():
    board = load_leaderboard(DEFAULT_FILE)
    names = [d.name for d in board.defences]
    assert set(NEW_DEFENCES) | set(STUDY_ROWS) | {"baseline"} <= set(names)
    town07 = next(p for p in board.places if p.label == "town07 standard")
    assert town07.seeds >= 10
    runs = board.runs()
    assert {r.kind for r in runs} == {SAFETY, AVAILABILITY}
    assert all(r.config.scenario.stop_required for r in runs if r.kind == SAFETY)
    assert not any(r.config.scenario.stop_required for r in runs if r.kind == AVAILABILITY)
    # Only map readers face the map's phantom stop; nobody else reads the map.
    phantom = {r.defence for r in runs if r.config.scenario.map_error == "phantom_stop"}
    assert phantom == {"map_prior", "autopilot"}


def test_the_quick_subset_is_part_of_the_full_board_so_a_resume_reuses_it():
    board = load_leaderboard(DEFAULT_FILE)
    quick = {s.spec_hash for s in unique_specs(board, board.runs(quick=True))}
    full = {s.spec_hash for s in unique_specs(board, board.runs())}
    assert quick < full


def test_a_placeholder_adaptive_attack_runs_once(tmp_path):
    board = load_leaderboard(write(tmp_path, TINY))
    runs = [r for r in board.runs() if r.defence == "baseline" and r.kind == SAFETY]
    assert len(list(unique_specs(board, runs))) == len(runs) * 2 // 3  # its adaptive texture is the strongest one
    runs = [r for r in board.runs() if r.defence == "map_prior" and r.kind == SAFETY]
    assert len(list(unique_specs(board, runs))) == len(runs)  # its adaptive condition differs


def test_every_shipped_defence_faces_an_adaptive_attack_of_its_own():
    board = load_leaderboard(DEFAULT_FILE)
    strongest = board.conditions["strongest"].overrides
    every_run = board.runs()  # once: the board's runs are built anew at each call
    for defence in board.defences:
        assert defence.adaptive.overrides != strongest, defence.name
        runs = [r for r in every_run if r.defence == defence.name and r.kind == SAFETY]
        assert len(list(unique_specs(board, runs))) == len(runs), defence.name


# ---- the format's checks -------------------------------------------------------------------------

@pytest.mark.parametrize("change, message", [
    (("adaptive = { scenario = { sign = \"yang\", map_error = \"missing_stop\" } }\n", ""), "no 'adaptive' table"),
    (("[conditions.strongest]\nnote = \"stand-in\"\nscenario = { sign = \"yang\" }", "[conditions.strongest]\nscenario = { sign = \"none\" }"),
     "has no stop to make"),
    (("scenario = { sign = \"none\" }\nseeds = 1\nquick_seeds = 1", "scenario = { sign = \"clean\" }\nseeds = 1\nquick_seeds = 1"),
     "requires a stop"),
    (("defences = [\"map_prior\"]", "defences = [\"nobody\"]"), "no defence of this file"),
    (("name = \"map_prior\"", "name = \"baseline\""), "names 'baseline' twice"),
    (("seeds = 2\nquick_seeds = 1", "seeds = 2\nquick_seeds = 3"), "quick_seeds"),
    (("policy = { name = \"map_prior\" }", "policy = { name = \"map_priors\" }"), "policy"),
    (("scenario = { sign = \"yang\" }\n[[defences]]", "scenario = { sign = \"nosuchtexture\" }\n[[defences]]"),
     "unknown sign texture"),
    (("[conditions.clean]", "[conditions.dirty]\nscenario = {}\n[conditions.clean]"), "unknown condition 'dirty'"),
    # A bad key is named with its place in the file, not only the key.
    (("policy = { name = \"map_prior\" }", "policy = { name = \"map_prior\", bogus = 1 }"),
     r"defences\[1\] \"map_prior\": unknown config key 'policy.bogus'"),
    (("[conditions.strongest]\nnote = \"stand-in\"\nscenario = { sign = \"yang\" }",
      "[conditions.strongest]\nnote = \"stand-in\"\nscenario = { sign = \"yang\", bogus = 1 }"),
     r"\[conditions\]: unknown config key 'scenario.bogus'"),
    (("name = \"no stop sign\"\nscenario = { sign = \"none\" }", "name = \"no stop sign\"\nscenario = { sign = \"none\", bogus = 1 }"),
     r"availability\[0\] \"no stop sign\": unknown config key 'scenario.bogus'"),
])
def test_every_run_is_checked_when_the_file_loads(tmp_path, change, message):
    old, new = change
    assert old in TINY
    with pytest.raises(ConfigError, match=message):
        load_leaderboard(write(tmp_path, TINY.replace(old, new, 1)))


# ---- a small board, end to end -------------------------------------------------------------------

@pytest.mark.slow  # about 50 s: a board of closed-loop runs, then its resumption
def test_a_small_board_runs_writes_its_report_and_resumes_without_running_again(tmp_path, capsys):
    path = write(tmp_path, TINY)
    out = tmp_path / "out"
    assert main(["leaderboard", str(path), "--out", str(out), "--quick", "--workers", "1", "--no-progress"]) == 0
    assert {"leaderboard.md", "leaderboard.png", "results.jsonl", "manifest.json", "leaderboard.toml"} <= {p.name for p in out.iterdir()}
    records = read_records(out / "results.jsonl")
    manifest = json.loads((out / "manifest.json").read_text())
    # baseline: clean, yang (its adaptive is the same config), no sign; map_prior: clean, yang, yang without map, no sign.
    assert manifest["runs"] == 8 and manifest["configs"] == len(records) == 7 and manifest["failed"] == 0
    report = (out / "leaderboard.md").read_text()
    assert "| baseline |" in report or "| **baseline** |" in report
    assert "placeholder" in report  # the adaptive note

    # The full board reuses the quick runs; running it again runs nothing.
    assert main(["leaderboard", str(path), "--out", str(out), "--workers", "1", "--no-progress", "--resume"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["reused"] == 7 and manifest["ran"] == manifest["configs"] - 7
    assert main(["leaderboard", str(path), "--out", str(out), "--workers", "1", "--no-progress", "--resume"]) == 0
    assert json.loads((out / "manifest.json").read_text())["ran"] == 0
    capsys.readouterr()

    board = load_leaderboard(path)
    table = {row.name: row for row in rows(board, Results(board.runs(), read_records(out / "results.jsonl")))}
    # The map prior stops for the mapped stop that is not there: its availability cost.
    assert table["map_prior"].phantom == (1, 2) and table["baseline"].phantom == (0, 1)
    # With the oracle nothing hides the sign; without a mapped stop the camera still stops the map prior.
    assert table["baseline"].attacked == (2, 2) and table["map_prior"].attacked == (4, 4)
    assert table["baseline"].frames_per_step == 0  # the oracle runs no network
    assert pareto_front(table.values()) == {"baseline"}


def test_a_stop_that_came_to_rest_beyond_the_braking_gate_is_counted_beside_its_conditions_stop_rate(tmp_path):
    board = load_leaderboard(write(tmp_path, TINY))
    runs = [run for run in board.runs() if run.kind == SAFETY]
    # Every run stops; the attacked ones (yang) 98 m before the line, beyond the 40 m gate, the clean ones 7 m before it.
    records = [{"spec_hash": config_hash(run.config), "status": "ok", "wall_s": 1.0, "cell": run.defence, "seed": 0,
                "result": {"outcome": "stopped_before_line", "stop_required": True, "sign_margin_m": margin + 1.0,
                           "margin_m": margin, "config": run.config.to_dict()}}
               for run in runs for margin in [98.2 if run.config.scenario.sign == "yang" else 7.3]]
    table = {tuple(c.strip() for c in line.strip("|").split("|")[:2]): line
             for line in condition_table(board, Results(runs, records)) if line.startswith("| ") and "condition" not in line}
    assert "2/2 (0.34–1.00); 2 at rest beyond the gate" in table[("baseline", "strongest")]
    assert "beyond" not in table[("baseline", "clean")] and "2/2 (0.34–1.00) |" in table[("baseline", "clean")]


def test_an_existing_board_folder_is_not_overwritten_without_resume(tmp_path):
    path = write(tmp_path, TINY)  # refused before its first run (a board of no runs is refused on its own)
    out = tmp_path / "out"
    out.mkdir()
    shutil.copy(path, out / "results.jsonl")  # anything there that is not avsim's
    with pytest.raises(ConfigError, match="not an avsim results file"):
        run_leaderboard(load_leaderboard(path), out, quick=True, workers=1, progress=False)


# The shipped board with its approach cut from 150 m to 60 m before the stop line: every run still
# starts 20 m (0.85 s at 85 km/h) before the 40 m gate, so each defence sees the sign, decides and
# brakes (or runs on) as on the board, in about half the simulated time.
SHORT_APPROACH_M = 60


def test_a_resume_with_other_set_values_than_the_folders_is_refused_before_anything_runs(tmp_path, capsys):
    path = write(tmp_path, TINY)
    out = tmp_path / "board"
    out.mkdir()
    (out / "set.json").write_text('{"set": {"scenario.start_dist_m": 60}}')
    (out / "results.jsonl").write_text('{"status": "ok"}\n')  # runs there: refused before they are read
    before = sorted(out.rglob("*"))
    assert main(["leaderboard", str(path), "--out", str(out), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "its runs were given --set scenario.start_dist_m=60 and this command no --set" in err
    assert sorted(out.rglob("*")) == before


def test_a_resume_under_another_setting_than_the_folders_is_refused_before_anything_runs(tmp_path, capsys):
    path = write(tmp_path, TINY)
    out = tmp_path / "board"
    out.mkdir()
    (out / "setting.json").write_text('{"setting": "sheeting"}')
    (out / "results.jsonl").write_text('{"status": "ok"}\n')
    before = sorted(out.rglob("*"))
    assert main(["leaderboard", str(path), "--out", str(out), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "rendered under --setting sheeting and this avsim leaderboard under --setting baseline" in err
    assert sorted(out.rglob("*")) == before


def test_a_leaderboard_under_a_set_gives_every_run_the_value(tmp_path):
    path = write(tmp_path, TINY)
    board = load_leaderboard(path, overrides=parse_set(["scenario.start_dist_m=60"]))
    assert {run.config.scenario.start_dist_m for run in board.runs()} == {60.0}
    assert board.set_items == (("scenario.start_dist_m", 60),) and "(with --set scenario.start_dist_m=60)" in board.title


@pytest.mark.parametrize("item, where", [
    ("scenario.sign=clean", 'condition "clean"'),
    ("policy.name=adjusted", 'defence "baseline"'),
    ("scenario.town=town10", "[[places]]"),
    ("scenario.map_error=none", 'defence "map_prior"\'s adaptive condition'),
    ("scenario.sun_elevation_deg=50", "[vary]"),
])
def test_a_set_a_leaderboards_rows_would_override_is_refused(tmp_path, item, where):
    path = write(tmp_path, TINY)
    key = item.split("=")[0]
    with pytest.raises(ConfigError) as refused:
        load_leaderboard(path, overrides=parse_set([item]))
    assert f"{path}: {where} sets {key} itself" in str(refused.value), str(refused.value)


@pytest.mark.slow
@pytest.mark.both_cores  # two worker processes
def test_the_quick_leaderboard_runs_every_defence(tmp_path, capsys):
    """`avsim leaderboard --quick` on the shipped board: every defence, condition and road of its quick
    subset (Town07 standard, one seed) with the learned detector (and COCO for the ensembles), on a
    shorter approach."""
    text = DEFAULT_FILE.read_text()
    start = "start_dist_m = 150 }"
    assert text.count(start) == 1
    path = write(tmp_path, text.replace(start, f"start_dist_m = {SHORT_APPROACH_M} }}"))
    out = tmp_path / "board"
    assert main(["leaderboard", str(path), "--quick", "--out", str(out), "--workers", "2", "--no-progress"]) == 0
    capsys.readouterr()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["failed"] == 0
    board = load_leaderboard(path)
    assert {d.name for d in board.defences} == {d.name for d in load_leaderboard(DEFAULT_FILE).defences}
    table = {row.name: row for row in rows(board, Results(board.runs(quick=True), read_records(out / "results.jsonl")))}
    assert set(table) == {d.name for d in board.defences}
    for row in table.values():
        assert row.attacked[1] >= 1 and row.clean[1] == 1 and row.phantom[1] >= 1
    assert pareto_front(table.values())
    assert (out / "leaderboard.png").stat().st_size > 10_000


def test_the_plan_size_is_counted_without_building_runs_and_a_huge_board_needs_yes(tmp_path, capsys):
    tiny = load_leaderboard(write(tmp_path, TINY))
    assert tiny.size() == len(tiny.runs()) == 15 and tiny.size(quick=True) == len(tiny.runs(quick=True)) == 8
    huge = write(tmp_path, TINY.replace("seeds = 2\nquick_seeds = 1", "seeds = 9000\nquick_seeds = 1", 1))
    assert load_leaderboard(huge, quick=True).size(quick=True) == 8  # the quick subset needs no --yes
    assert main(["leaderboard", str(huge), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "54,003 runs" in err and "--yes" in err, err
    assert not (tmp_path / "out").exists()
