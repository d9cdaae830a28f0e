"""The attack metrics on synthetic data: which detection stands for the sign, disappearance by
distance, first confident detection and its delay, closed-loop success with its Wilson interval,
and the report section that shows them."""

import json
from pathlib import Path

import pytest

from avsim.experiments.attacks.disappearance import DriveBys, Frame
from avsim.experiments.attacks.drive_by_report import delay_m, disappearance_section, mean_first_m, transfer_section
from avsim.experiments.attacks.texture_eval import sign_detection
from avsim.experiments.attacks.success import success, success_row
from avsim.experiments.spec import load_experiment
from avsim.perception.base import Detection

ROOT = Path(__file__).resolve().parents[3]
ATTACK_EXPERIMENTS = ROOT / "experiments" / "attacks"


def test_a_confident_box_elsewhere_never_stands_for_the_sign():
    truth = Detection("stop_sign", 1.0, (400.0, 100.0, 420.0, 120.0), "front")
    tree = Detection("stop_sign", 0.9, (100.0, 150.0, 130.0, 180.0), "front")  # found[0]: the most confident
    sign = Detection("stop_sign", 0.4, (401.0, 101.0, 421.0, 121.0), "front")
    assert sign_detection([tree, sign], truth) is sign
    assert sign_detection([tree], truth) is None


def _drives(confidences_by_drive: dict[int, list[tuple[float, float]]], estimate_offset_m: float = 1.0) -> DriveBys:
    result = DriveBys("x", "detector", "town07", "standard", 0.5, 40.0)
    for drive, frames in confidences_by_drive.items():
        for dist, conf in frames:
            result.frames.append(Frame(drive, dist, conf, 10.0 if conf else 0.0, 10.0,
                                       dist - estimate_offset_m if conf else None))
    return result


def test_disappearance_counts_frames_below_the_threshold_per_bin():
    result = _drives({0: [(44.0, 0.9), (42.0, 0.2), (38.0, 0.6), (36.0, 0.0), (31.0, 0.55)]})
    frames, missed, rate, (low, high) = result.disappearance(35.0, 45.0)
    assert (frames, missed, rate) == (4, 2, 0.5)
    assert low < 0.5 < high
    # Any range: 44 m; inside the gate (estimate <= 40 m): 38 m.
    assert result.first_confident_m(0, gated=False) == 44.0
    assert result.first_confident_m(0, gated=True) == 38.0


def test_the_delay_is_paired_by_drive_and_a_sign_never_seen_counts_to_its_last_frame():
    clean = _drives({0: [(40.0, 0.9), (30.0, 0.9)], 1: [(39.0, 0.9), (29.0, 0.9)]})
    attacked = _drives({0: [(40.0, 0.1), (30.0, 0.7)], 1: [(39.0, 0.1), (29.0, 0.1)]})
    assert delay_m(attacked, clean, gated=True) == pytest.approx(((40 - 30) + (39 - 29)) / 2)
    assert mean_first_m(attacked, gated=True) == (30.0, 1)
    lines = "\n".join(disappearance_section({("clean", "detector"): clean, ("x", "detector"): attacked}, {}))
    assert "| x |" in lines and "1/2" in lines
    assert "| x | detector |" in "\n".join(transfer_section({("x", "detector"): attacked}, {"x": "detector"}))


def _result(outcome: str, margin: float, brake: float | None) -> dict:
    return {"outcome": outcome, "sign_margin_m": margin, "dist_at_brake_m": brake}


def test_success_rate_overrun_and_braking_delay():
    results = [_result("ran_past_sign", -12.0, 30.0), _result("stopped_before_line", 3.0, 39.0),
               _result("never_braked", -40.0, None), _result("ran_past_sign", -4.0, 33.0)]
    clean = {0: _result("stopped_before_line", 5.0, 40.0), 1: _result("stopped_before_line", 5.0, 40.0),
             3: _result("stopped_before_line", 5.0, 39.0)}
    s = success(results, [0, 1, 2, 3], clean)
    assert (s.runs, s.past, s.never_braked) == (4, 3, 1)
    assert s.rate == 0.75 and s.ci95[0] < 0.75 < s.ci95[1]
    assert s.overrun_mean_m == pytest.approx((12 + 40 + 4) / 3) and s.overrun_worst_m == 40.0
    assert s.brake_delay_mean_m == pytest.approx(((40 - 30) + (40 - 39) + (39 - 33)) / 3)
    assert success_row(s)[0] == "3/4 (1 never braked)"


def test_the_attack_success_report_pairs_each_cell_with_its_clean_cell(tmp_path):
    from avsim.experiments.report_cells import Cells
    from avsim.experiments.report_sections import attack_success_section

    path = tmp_path / "success.toml"
    path.write_text('title = "t"\nseeds = 2\nreport = "attack_success"\n[defaults]\npolicy = { name = "baseline" }\n'
                    '[[cells]]\nname = "clean"\nscenario = { sign = "clean" }\n'
                    '[[cells]]\nname = "attacked"\nscenario = { sign = "yang" }\n')
    experiment = load_experiment(path)
    records = [{"experiment": "success", "cell": cell, "seed": seed, "status": "ok", "trace": {},
                "result": _result(outcome, margin, brake)}
               for cell, seed, outcome, margin, brake in [("clean", 0, "stopped_before_line", 5.0, 40.0),
                                                           ("clean", 1, "stopped_before_line", 5.0, 41.0),
                                                           ("attacked", 0, "ran_past_sign", -11.0, 28.0),
                                                           ("attacked", 1, "stopped_past_line", 0.5, 36.0)]]
    text = "\n".join(attack_success_section(Cells(records), experiment))
    assert "| attacked | yang | detector | town07 standard | baseline | 1/2 |" in text
    assert "| 11.0 | 11.0 | 32.0 | 8.5 |" in text  # overrun mean and worst, braking began, delay ((40-28)+(41-36))/2


def test_the_attack_experiment_files_load_with_their_seeds():
    # file name -> (seeds, the report kind it declares)
    expected = {"success_town07.toml": (20, "attack_success"), "success_towns.toml": (5, "attack_success"),
                "success_coco.toml": (20, "attack_success"), "success_coco_towns.toml": (5, "attack_success"),
                "range_inflation_adjusted.toml": (20, "attack_success"),
                "driveby_detector_town07.toml": (20, "attack_success"),
                "sensitivity_coco_town10.toml": (5, "sensitivity"),
                "success_yolo.toml": (20, "attack_success"), "success_yolo_towns.toml": (5, "attack_success"),
                "sensitivity_yolo_town03.toml": (5, "sensitivity"),
                "success_yolo_textures.toml": (20, "attack_success"),
                "success_yolo_textures_town07.toml": (5, "attack_success"),
                "success_yolo_textures_towns.toml": (5, "attack_success"), "driveby_yolo.toml": (10, "attack_success")}
    assert sorted(p.name for p in ATTACK_EXPERIMENTS.glob("*.toml")) == sorted(expected)
    for name, (seeds, report) in expected.items():
        experiment = load_experiment(ATTACK_EXPERIMENTS / name)
        assert experiment.seeds == seeds and experiment.report == report
        assert any(c.config.scenario.sign == "clean" for c in experiment.cells)  # the pair for the braking delay
    for name in ("success_towns.toml", "success_coco_towns.toml", "success_yolo_towns.toml"):
        towns = load_experiment(ATTACK_EXPERIMENTS / name)
        cells = {(c.config.scenario.town, c.config.scenario.placement) for c in towns.cells}
        assert len(cells) == 8 and ("town07", "standard") not in cells


def signs_by_place(experiment) -> dict[tuple[str, str], set[str]]:
    """(town, placement) -> the signs an experiment file's cells put there."""
    places: dict[tuple[str, str], set[str]] = {}
    for c in experiment.cells:
        places.setdefault((c.config.scenario.town, c.config.scenario.placement), set()).add(c.config.scenario.sign)
    return places


def test_the_attack_success_files_measure_every_shipped_texture_in_every_cell_under_both_detectors():
    """Issue 14: closed-loop success per texture and detector, in Town07 standard and the other 8 cells."""
    budget_points = {"yang_eps0.09", "yang_eps0.18"}  # yang at smaller budgets: the safety map's axis, not attacks
    # Made against all three networks (issue 29): its closed loop is the three-network board's
    # (experiments/leaderboards/three_networks.toml), where the networks it targets perceive.
    three_networks = {"driveby_ensemble_all", "driveby_ensemble_all_2of3"}
    # Made against YOLOv3-tiny alone: its closed loop is under YOLOv3-tiny (driveby_yolo.toml).
    yolo_only = {"driveby_yolo"}
    shipped = {"clean"} | {p.stem for p in (ROOT / "textures").glob("*.json")} - budget_points - three_networks - yolo_only
    assert len(shipped) == 15
    for name, kind, places in (("success_town07.toml", "detector", 1), ("success_towns.toml", "detector", 8),
                               ("success_coco.toml", "coco", 1), ("success_coco_towns.toml", "coco", 8)):
        experiment = load_experiment(ATTACK_EXPERIMENTS / name)
        assert {c.config.perception.kind for c in experiment.cells} == {kind}
        assert {c.config.policy.name for c in experiment.cells} == {"baseline"}
        signs = signs_by_place(experiment)
        assert len(signs) == places, name
        assert all(at_place == shipped for at_place in signs.values()), name


def test_the_yolo_transfer_files_pair_the_clean_sign_with_the_own_detectors_drive_by_texture_in_every_cell():
    """Issue 29: does a texture made against avsim's own detector make baseline run the sign under YOLOv3-tiny?
    20 seeds in Town07 standard, 5 in each other cell."""
    places_seen = set()
    for name, places in (("success_yolo.toml", 1), ("success_yolo_towns.toml", 8)):
        experiment = load_experiment(ATTACK_EXPERIMENTS / name)
        assert {c.config.perception.kind for c in experiment.cells} == {"yolo"}
        assert {c.config.policy.name for c in experiment.cells} == {"baseline"}
        signs = signs_by_place(experiment)
        assert len(signs) == places
        assert all(at_place == {"clean", "driveby_detector"} for at_place in signs.values())
        places_seen |= set(signs)
    assert len(places_seen) == 9


def test_the_yolo_texture_files_pair_every_texture_made_against_the_own_detector_with_the_clean_sign():
    """Issue 29: does any texture made against avsim's own detector make baseline run the sign under
    YOLOv3-tiny? Every such texture, 20 seeds in Town07 standard and 5 in each other cell, in one precision."""
    own = {p.stem for p in (ROOT / "textures").glob("*.json") if json.loads(p.read_text())["detector"] == "detector"}
    assert len(own) == 14
    places_seen = set()
    for name, seeds, places in (("success_yolo_textures.toml", 20, 1), ("success_yolo_textures_town07.toml", 5, 2),
                                ("success_yolo_textures_towns.toml", 5, 6)):
        experiment = load_experiment(ATTACK_EXPERIMENTS / name)
        assert experiment.seeds == seeds
        assert {(c.config.perception.kind, c.config.perception.yolo_precision, c.config.policy.name)
                for c in experiment.cells} == {("yolo", "auto", "baseline")}
        signs = signs_by_place(experiment)
        assert len(signs) == places
        assert all(at_place == own | {"clean"} for at_place in signs.values()), name
        places_seen |= set(signs)
    assert len(places_seen) == 9 and ("town07", "standard") in places_seen


def test_the_texture_made_against_yolo_is_paired_with_the_clean_sign_at_the_gate_and_without_it():
    """driveby_yolo's closed loop: Town07 standard at the 40 m gate, and Town03 near without a gate, where
    YOLOv3-tiny's legend box does not already run the clean sign past."""
    experiment = load_experiment(ATTACK_EXPERIMENTS / "driveby_yolo.toml")
    cells = {(c.config.scenario.sign, c.config.scenario.town, c.config.scenario.placement, c.config.policy.trigger_dist_m)
             for c in experiment.cells}
    assert cells == {(sign, *place) for sign in ("clean", "driveby_yolo")
                     for place in (("town07", "standard", 40.0), ("town03", "near", None))}  # inf: no gate
    assert {(c.config.perception.kind, c.config.policy.name) for c in experiment.cells} == {("yolo", "baseline")}
    assert json.loads((ROOT / "textures" / "driveby_yolo.json").read_text())["detector"] == "yolo"


def test_a_texture_source_names_its_detector_and_the_purification_it_went_through():
    from avsim.experiments.attacks.drive_by_report import source_of

    assert source_of({}) == "-"
    assert source_of({"detector": "coco"}) == "coco"
    assert source_of({"method": "yang"}) == "detector"  # records from before targets were named
    assert source_of({"detector": "detector", "purify": {"purify": "jpeg", "purify_jpeg_quality": 75}}) == "detector + jpeg"


def test_the_coco_sensitivity_file_varies_the_gate_and_the_threshold_one_at_a_time_for_both_signs():
    experiment = load_experiment(ATTACK_EXPERIMENTS / "sensitivity_coco_town10.toml")
    for sign in ("clean", "driveby_coco"):
        cells = [c.config for c in experiment.cells if c.config.scenario.sign == sign]
        assert {(c.policy.trigger_dist_m, c.policy.conf_threshold) for c in cells} == {
            (30.0, 0.5), (40.0, 0.5), (60.0, 0.5), (None, 0.5), (40.0, 0.3), (40.0, 0.7)}
        assert {(c.perception.kind, c.policy.name, c.scenario.town, c.scenario.placement) for c in cells} == {
            ("coco", "baseline", "town10", "near")}
