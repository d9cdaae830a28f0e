"""Experiment files: the shipped tables load and expand; every malformed file is a one-line ConfigError."""

from __future__ import annotations

from pathlib import Path

import pytest

import avsim.loop
import avsim.runner
from avsim import cli
from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.experiments import load_experiment
from avsim.experiments.spec import config_at_seed
from avsim.realism.settings import SETTINGS

EXPERIMENTS_DIR = Path(__file__).resolve().parents[2] / "experiments"
TABLE3 = EXPERIMENTS_DIR / "table3_stop_positions.toml"
DEFENDED_CELLS = [("town07", "standard"), ("town03", "far"), ("town03", "near"), ("town10", "far"), ("town10", "near")]

# file name -> (sign, policy) of each cell, in order
SHIPPED = {
    "table3_stop_positions.toml": [("clean", "baseline"), ("yang", "baseline"), ("yang", "adjusted"),
                                   ("yang", "side_camera"), ("clean", "autopilot")],
    "table1_clean_defended.toml": [("clean", "combined")] * 5,
    "table2_attacked_defended.toml": [("yang", "combined")] * 5,
    "fig3_detection.toml": [(sign, "baseline") for sign in ("clean", "chen", "eykholt", "lu_v2", "lu_v3", "yang")],
    "adaptive_attacker.toml": [("adaptive", "baseline"), ("adaptive", "side_camera"), ("adaptive", "adjusted"),
                               ("adaptive", "combined"), ("driveby_side", "side_camera"), ("driveby_side", "combined"),
                               ("yang", "side_camera")],
    "wet_road.toml": [("clean", "baseline"), ("yang", "baseline"), ("clean", "adjusted"), ("yang", "adjusted"),
                      ("clean", "side_camera"), ("yang", "side_camera"), ("clean", "autopilot")],
    "sensitivity.toml": [(sign, policy) for policy in ("baseline", "adjusted") for sign in ("clean", "yang") for _ in range(6)],
    "coco_detector.toml": [("clean", policy) for _ in range(9)
                           for policy in ("baseline", "adjusted", "side_camera", "combined", "study_stack")],
    "yolo_detector.toml": [("clean", policy) for _ in range(9)
                           for policy in ("baseline", "adjusted", "side_camera", "combined", "study_stack")],
}
# Table III under the two COCO-trained networks: the same cells as the own detector's
SHIPPED["table3_coco.toml"] = SHIPPED["table3_yolo.toml"] = SHIPPED["table3_stop_positions.toml"]
SHIPPED["table3_yolo_clusters.toml"] = SHIPPED["table3_stop_positions.toml"]
# The COCO closed loop in Town10 under three scenes (flat, sheeting, sheeting and textured)
SHIPPED["coco_detector_realism.toml"] = [("clean", policy) for _ in range(3 * 2) for policy in ("baseline", "adjusted")]
# Its Town10 standard and far cells alone, to run under a render setting (`--setting`)
SHIPPED["coco_detector_town10.toml"] = [("clean", policy) for _ in range(2) for policy in ("baseline", "adjusted")]
# Table III's four cells that see, under six scenes (flat, textured, clusters, all, daylight, no_shadows)
SCENES_OF_TABLE3_REALISM = ("flat", "textured", "clusters", "all", "daylight", "no_shadows")
SHIPPED["table3_realism.toml"] = SHIPPED["table3_stop_positions.toml"][:4] * len(SCENES_OF_TABLE3_REALISM)
# Table III's yang cells (baseline, side_camera) at seven sky levels, and the clean sign at the two ends
SKY_LEVELS_EV = (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5)
SHIPPED["sky_brightness.toml"] = [("clean", "baseline")] * 2 + [("yang", p) for _ in SKY_LEVELS_EV for p in ("baseline", "side_camera")]
# file name -> seeds per cell, where not 5
SEEDS = {"coco_detector_realism.toml": 10, "table3_realism.toml": 10, "sky_brightness.toml": 10}
# file name -> the report section it declares
REPORT_KIND = {"table3_stop_positions.toml": "table3", "table1_clean_defended.toml": "table1",
               "table2_attacked_defended.toml": "table2", "fig3_detection.toml": "fig3",
               "adaptive_attacker.toml": "adaptive", "wet_road.toml": "compare", "sensitivity.toml": "sensitivity",
               "coco_detector.toml": "stop_rates", "yolo_detector.toml": "stop_rates",
               "table3_coco.toml": "table3", "table3_yolo.toml": "table3",
               "table3_yolo_clusters.toml": "table3", "coco_detector_realism.toml": "cells",
               "coco_detector_town10.toml": "stop_rates", "table3_realism.toml": "cells", "sky_brightness.toml": "cells"}
# file name -> the perception its runs see through (avsim's own detector where not named)
PERCEPTION_KIND = {"coco_detector.toml": "coco", "yolo_detector.toml": "yolo", "table3_coco.toml": "coco",
                   "table3_yolo.toml": "yolo", "table3_yolo_clusters.toml": "yolo", "coco_detector_realism.toml": "coco",
                   "coco_detector_town10.toml": "coco"}
# files whose cells cover every town and placement (the rest are Town07 standard)
EVERY_PLACE = ("coco_detector.toml", "yolo_detector.toml")
EVERY_TOWN_AND_PLACEMENT = [(town, placement) for town in ("town03", "town07", "town10") for placement in ("near", "standard", "far")]


# ---- the shipped files ------------------------------------------------------------------

def test_the_sensitivity_file_varies_the_gate_and_the_threshold_one_at_a_time():
    experiment = load_experiment(EXPERIMENTS_DIR / "sensitivity.toml")
    pairs = {(c.config.policy.trigger_dist_m, c.config.policy.conf_threshold) for c in experiment.cells}
    assert pairs == {(30.0, 0.5), (40.0, 0.5), (60.0, 0.5), (None, 0.5), (40.0, 0.3), (40.0, 0.7)}


def test_every_shipped_file_is_tested():
    assert sorted(p.name for p in EXPERIMENTS_DIR.glob("*.toml")) == sorted(SHIPPED)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_file_loads_with_the_study_cells(name):
    experiment = load_experiment(EXPERIMENTS_DIR / name)
    assert experiment.seeds == SEEDS.get(name, 5)
    assert [(c.config.scenario.sign, c.config.policy.name) for c in experiment.cells] == SHIPPED[name]
    for cell in experiment.cells:
        assert cell.config.scenario.speed_kmh == 85.0
        assert cell.config.perception.kind == PERCEPTION_KIND.get(name, "detector")
        assert cell.config.perception.sensor_noise_std == 2.0
    assert experiment.report == REPORT_KIND[name]
    road = {c.config.scenario.road_friction for c in experiment.cells}
    assert road == ({0.5} if name == "wet_road.toml" else {0.9})
    places = [(c.config.scenario.town, c.config.scenario.placement) for c in experiment.cells]
    if "defended" in name:
        assert places == DEFENDED_CELLS
    elif name in EVERY_PLACE:
        assert places == [place for place in EVERY_TOWN_AND_PLACEMENT for _ in range(5)]
    elif name == "coco_detector_realism.toml":
        assert places == [("town10", placement) for _ in range(3) for placement in ("standard", "far") for _ in range(2)]
    elif name == "coco_detector_town10.toml":
        assert places == [("town10", placement) for placement in ("standard", "far") for _ in range(2)]
    else:
        assert {(c.config.scenario.town, c.config.scenario.placement) for c in experiment.cells} == {("town07", "standard")}


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_file_expands_to_cells_times_seeds_runs(name):
    experiment = load_experiment(EXPERIMENTS_DIR / name)
    runs = experiment.runs()
    seeds = SEEDS.get(name, 5)
    assert len(runs) == len(SHIPPED[name]) * seeds
    assert [(r.cell_name, r.seed) for r in runs] == [(c.name, s) for c in experiment.cells for s in range(seeds)]
    for run in runs:
        assert run.config.scenario.seed == run.seed
        # Apart from the seed and the varied lighting, a run is its cell.
        cell = experiment.cell(run.cell_name)
        assert run.config.policy == cell.config.policy
        assert run.config.scenario.sign == cell.config.scenario.sign


def test_the_coco_realism_file_is_coco_detectors_town10_cells_under_three_scenes():
    realism = load_experiment(EXPERIMENTS_DIR / "coco_detector_realism.toml")
    coco = load_experiment(EXPERIMENTS_DIR / "coco_detector.toml")
    scenes = {"flat": {}, "sheeting": {"sign_materials": "sheeting"},
              "textured": {"sign_materials": "sheeting", "materials": "textured"}}
    _assert_runs_are_the_references_under_scenes(realism, coco, scenes)


def test_the_coco_town10_file_is_coco_detectors_town10_standard_and_far_runs_config_for_config():
    town10 = load_experiment(EXPERIMENTS_DIR / "coco_detector_town10.toml")
    coco = load_experiment(EXPERIMENTS_DIR / "coco_detector.toml")
    coco_runs = {(r.cell_name, r.seed): r.config for r in coco.runs()}
    runs = town10.runs()
    assert runs and all(coco_runs[(run.cell_name, run.seed)] == run.config for run in runs)


def test_the_table3_realism_file_is_table3s_cells_under_six_scenes():
    realism = load_experiment(EXPERIMENTS_DIR / "table3_realism.toml")
    table3 = load_experiment(TABLE3)
    # Each scene is one of `avsim realism`'s settings, so the benchmark and `attack eval --setting` measure it too.
    scenes = {scene: dict(SETTINGS[setting].overrides["scenario"]) if setting != "baseline" else {}
              for scene, setting in (("flat", "baseline"), ("textured", "textured"), ("clusters", "clusters"),
                                     ("all", "textured_sheeting_clusters_shadows"), ("daylight", "daylight_sky"),
                                     ("no_shadows", "full_scene_no_shadows"))}
    assert scenes["all"] == {"materials": "textured", "sign_materials": "sheeting", "foliage": "clusters",
                             "sun_shadow_map_px": 4096}
    assert tuple(scenes) == SCENES_OF_TABLE3_REALISM
    _assert_runs_are_the_references_under_scenes(realism, table3, scenes)


def test_the_sky_brightness_file_is_table3s_cells_with_only_the_skys_level_changed():
    sky = load_experiment(EXPERIMENTS_DIR / "sky_brightness.toml")
    table3 = load_experiment(TABLE3)
    levels = {(f"{ev:+.1f} EV" if ev else "0.0 EV"): {"sky_exposure_ev": ev} for ev in SKY_LEVELS_EV}
    _assert_runs_are_the_references_under_scenes(sky, table3, levels)
    # At 0 EV the runs are Table III's own, config for config: the default sky.
    zero = [run for run in sky.runs() if run.cell_name.endswith(", 0.0 EV")]
    assert zero and all(run.config.scenario.sky_exposure_ev == 0.0 for run in zero)


def _assert_runs_are_the_references_under_scenes(realism, reference, scenes: dict[str, dict]) -> None:
    """Each run of `realism`, a cell named "<reference cell>, <scene>", is `reference`'s run of that cell and
    seed with the scene's scenario overrides, and nothing else changed."""
    assert realism.vary == reference.vary
    reference_runs = {(r.cell_name, r.seed): r.config for r in reference.runs()}
    for run in realism.runs():
        cell, scene = run.cell_name.rsplit(", ", 1)
        # The reference file's run of that cell and seed (its seeds may end sooner; seed k draws the same light in any file).
        expected = config_at_seed(reference.cell(cell).config, reference.vary, run.seed)
        assert reference_runs.get((cell, run.seed), expected) == expected
        assert run.config == with_overrides(expected, {"scenario": scenes[scene]})


def test_runs_vary_lighting_per_seed_within_range_and_identically_across_cells():
    experiment = load_experiment(TABLE3)
    runs = experiment.runs()
    by_seed: dict[int, set[tuple[float, float, float]]] = {}
    for run in runs:
        sc = run.config.scenario
        assert 30 <= sc.sun_elevation_deg <= 70 and -180 <= sc.sun_azimuth_deg <= 180 and 0.8 <= sc.sun_intensity <= 1.2
        by_seed.setdefault(run.seed, set()).add((sc.sun_elevation_deg, sc.sun_azimuth_deg, sc.sun_intensity))
    assert all(len(lights) == 1 for lights in by_seed.values())  # seed k: same light in every cell
    assert len({next(iter(lights)) for lights in by_seed.values()}) == 5  # and different seeds differ
    assert runs == load_experiment(TABLE3).runs()  # deterministic


def test_cell_config_is_defaults_then_cell_over_simconfig(tmp_path):
    path = _write(tmp_path, """
        title = "t"
        seeds = 2
        [defaults]
        scenario = { town = "town03", speed_kmh = 60 }
        policy = { name = "adjusted", brake_multiplier = 0.8 }
        [[cells]]
        name = "a"
        scenario = { speed_kmh = 40 }
        [[cells]]
        name = "b"
        policy = { name = "baseline" }
    """)
    experiment = load_experiment(path)
    a, b = experiment.cells
    assert a.config == with_overrides(SimConfig(), {"scenario": {"town": "town03", "speed_kmh": 40},
                                                    "policy": {"name": "adjusted", "brake_multiplier": 0.8}})
    assert b.config.scenario.speed_kmh == 60 and b.config.policy.name == "baseline" and b.config.policy.brake_multiplier == 0.8
    assert experiment.vary == ()
    assert [r.config for r in experiment.runs()] == [with_overrides(c.config, {"scenario": {"seed": s}})
                                                     for c in (a, b) for s in (0, 1)]
    assert experiment.cell() is a and experiment.cell("b") is b


def test_textures_are_not_checked_at_load(tmp_path):
    # An attack texture may be written after the experiment file: the scene checks it when built.
    experiment = load_experiment(_write(tmp_path, '[[cells]]\nname = "x"\nscenario = { sign = "not_written_yet" }\n'))
    assert experiment.cells[0].config.scenario.sign == "not_written_yet"
    assert experiment.seeds == 5 and experiment.title == "exp"


# ---- errors -------------------------------------------------------------------------------

CELL = '[[cells]]\nname = "a"\n'
BAD_FILES = {
    "unknown_top_level_key": ('titel = "x"\n' + CELL, ["titel"]),
    "unknown_config_key": (CELL + '[[cells]]\nname = "b"\n[[cells]]\nname = "c"\npolicy = { nme = "baseline" }\n',
                           ["cells[2]", "policy.nme"]),
    "unknown_section": (CELL + "polcy = { name = 'baseline' }\n", ["cells[0]", "polcy"]),
    "unknown_default_key": ('[defaults]\nscenario = { twn = "town07" }\n' + CELL, ["[defaults]", "scenario.twn"]),
    "negative_speed": ('[[cells]]\nname = "a"\nscenario = { speed_kmh = -5 }\n', ["cells[0]", "scenario.speed_kmh"]),
    "wrong_type": ('[[cells]]\nname = "a"\nscenario = { speed_kmh = "fast" }\n', ["cells[0]", "scenario.speed_kmh"]),
    "unknown_town": ('[[cells]]\nname = "a"\nscenario = { town = "town99" }\n', ["cells[0]", "scenario.town", "town99"]),
    "unknown_policy": ('[defaults]\npolicy = { name = "brake_never" }\n' + CELL, ["[defaults]", "policy.name", "brake_never"]),
    "malformed_toml": ('title = "x"\n[[cells]\nname = "a"\n', ["malformed TOML", "line 2"]),
    "no_cells": ('title = "x"\n', ["cells"]),
    "empty_cells": ('title = "x"\ncells = []\n', ["cells"]),
    "duplicate_cell_names": (CELL + CELL, ["cells[1]", "duplicate", '"a"']),
    "cell_without_name": ('[[cells]]\npolicy = { name = "baseline" }\n', ["cells[0]", "name"]),
    "seeds_zero": ("seeds = 0\n" + CELL, ["seeds"]),
    "seeds_not_int": ("seeds = 2.5\n" + CELL, ["seeds"]),
    "seed_set_in_file": ('[[cells]]\nname = "a"\nscenario = { seed = 3 }\n', ["cells[0]", "scenario.seed"]),
    "vary_unknown_key": ("[vary]\nscenario = { sun_elev = [1, 2] }\n" + CELL, ["[vary]", "scenario.sun_elev"]),
    "vary_not_a_range": ("[vary]\nscenario = { sun_intensity = 1.0 }\n" + CELL, ["[vary]", "scenario.sun_intensity"]),
    "vary_int_key": ("[vary]\nscenario = { layout_seed = [0, 9] }\n" + CELL, ["[vary]", "scenario.layout_seed"]),
    "vary_out_of_range": ("[vary]\nscenario = { sun_intensity = [0.5, 3.0] }\n" + CELL, ["[vary]", "cells[0]", "scenario.sun_intensity"]),
    "unknown_report_kind": ('report = "table4"\n' + CELL, ["report", "table4", "table3"]),
    "compare_without_other": ('report = "compare"\n' + CELL, ["compare_with"]),
    "compare_with_without_compare": ('compare_with = "x"\n' + CELL, ["compare_with"]),
}


@pytest.mark.parametrize("text, mentions", list(BAD_FILES.values()), ids=list(BAD_FILES))
def test_bad_file_is_a_one_line_config_error_naming_file_and_key(tmp_path, text, mentions):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as excinfo:
        load_experiment(path)
    message = str(excinfo.value)
    assert "\n" not in message
    assert message.startswith(str(path))
    for mention in mentions:
        assert mention in message, message


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="not found") as excinfo:
        load_experiment(tmp_path / "nope.toml")
    assert str(tmp_path / "nope.toml") in str(excinfo.value)


def test_unknown_cell_name_lists_the_cells():
    with pytest.raises(ConfigError, match='"autopilot"') as excinfo:
        load_experiment(TABLE3).cell("autopilt")
    assert "autopilt" in str(excinfo.value)


# ---- avsim run --config ----------------------------------------------------------------------

@pytest.fixture
def captured_config(monkeypatch):
    """Replace the simulation by a stub that captures the config `avsim run` resolved."""
    captured: list[SimConfig] = []

    class _Stop(BaseException):  # not an Exception: cli.main's error boundary lets it through
        pass

    def _run_recorded(config, **recorders):
        captured.append(config)
        raise _Stop

    def _boom(self, *args, **kwargs):
        raise AssertionError("the CLI built a ClosedLoop; this test must not simulate")

    monkeypatch.setattr(avsim.runner, "run_recorded", _run_recorded)
    monkeypatch.setattr(avsim.loop.ClosedLoop, "__init__", _boom)

    def resolve(argv: list[str]) -> SimConfig:
        with pytest.raises(_Stop):
            cli.main(["run", *argv])
        return captured[-1]

    return resolve


def test_cli_runs_the_named_cell_at_seed_0(captured_config):
    config = captured_config(["--config", str(TABLE3), "--cell", "autopilot"])
    experiment = load_experiment(TABLE3)
    assert config == experiment.config_for(experiment.cell("autopilot"), 0)
    assert config.policy.name == "autopilot"


def test_cli_runs_the_first_cell_by_default(captured_config):
    config = captured_config(["--config", str(TABLE3)])
    experiment = load_experiment(TABLE3)
    assert config == experiment.config_for(experiment.cells[0], 0)


@pytest.mark.parametrize("seed_args", [["--seed", "3"], ["--set", "scenario.seed=3"]])
def test_cli_seed_picks_the_same_run_as_the_batch(captured_config, seed_args):
    # The [vary] lighting drawn for seed 3 comes with it, so one run can be replayed alone.
    config = captured_config(["--config", str(TABLE3), "--cell", "attacked sign, adjusted", *seed_args])
    run = next(r for r in load_experiment(TABLE3).runs() if r.cell_name == "attacked sign, adjusted" and r.seed == 3)
    assert config == run.config


def test_cli_flags_and_set_apply_on_top_of_the_cell(captured_config):
    config = captured_config(["--config", str(TABLE3), "--cell", "attacked sign, adjusted", "--seed", "3",
                              "--perception", "oracle", "--town", "town03", "--set", "scenario.town=town10",
                              "--set", "policy.brake_multiplier=0.7"])
    assert (config.scenario.seed, config.perception.kind, config.scenario.town) == (3, "oracle", "town10")
    assert config.scenario.sun_elevation_deg == load_experiment(TABLE3).runs()[3].config.scenario.sun_elevation_deg
    assert (config.policy.name, config.policy.brake_multiplier, config.scenario.sign) == ("adjusted", 0.7, "yang")


BAD_CLI = {
    "unknown_cell": (["--config", str(TABLE3), "--cell", "no such cell"], "no such cell"),
    "missing_file": (["--config", "experiments/nope.toml"], "nope.toml"),
    "cell_without_config": (["--cell", "autopilot"], "--config"),
    "bad_set_on_top": (["--config", str(TABLE3), "--set", "policy.nme=x"], "policy.nme"),
}


@pytest.mark.parametrize("argv, mention", list(BAD_CLI.values()), ids=list(BAD_CLI))
def test_cli_config_errors_exit_2_with_one_line(tmp_path, capsys, monkeypatch, argv, mention):
    def _boom(self, *args, **kwargs):
        raise AssertionError("the CLI started simulating before rejecting bad input")

    monkeypatch.setattr(avsim.loop.ClosedLoop, "__init__", _boom)
    out = tmp_path / "out.json"
    code = cli.main(["run", *argv, "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert len(captured.err.splitlines()) == 1 and captured.err.startswith("avsim: error:")
    assert mention in captured.err
    assert not out.exists()


def _write(tmp_path: Path, text: str, name: str = "exp.toml") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(line.strip() for line in text.splitlines()) + "\n")
    return path


@pytest.mark.parametrize("argv, named", [
    (["sweep", str(EXPERIMENTS_DIR / "table1_clean_defended.toml")], "a file for `avsim reproduce`, not a sweep file"),
    (["reproduce", "--experiments", str(EXPERIMENTS_DIR / "sweeps" / "sweep_smoke.toml")],
     "a file for `avsim sweep`, not an experiment file"),
    (["sweep", str(EXPERIMENTS_DIR / "leaderboards" / "defences.toml")], "a file for `avsim leaderboard`, not a sweep file"),
])
def test_a_file_given_to_another_command_names_the_command_that_runs_it(tmp_path, capsys, argv, named):
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and named in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_file_saved_with_a_byte_order_mark_says_so(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (EXPERIMENTS_DIR / "table1_clean_defended.toml").read_bytes())
    with pytest.raises(ConfigError, match="byte-order mark"):
        load_experiment(path)


def test_a_device_as_an_experiment_file_is_refused_without_reading_it():
    # The command line refuses it too (avsim.outputs); a library caller reaches this reader directly.
    with pytest.raises(ConfigError, match="is a device, not a regular file"):
        load_experiment(Path("/dev/zero"))
