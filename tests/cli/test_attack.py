"""`avsim attack eval --setting`, `--set` and `--weights`: every frame of the measurement is drawn under the named
render setting and values, and scored by the named weights."""

from pathlib import Path

import pytest

import avsim.experiments.attacks.disappearance as disappearance
import avsim.experiments.attacks.texture_eval as texture_eval
from avsim import cli


def _empty_report(sign: str, placements) -> texture_eval.TextureReport:
    """A report of `sign` in which the sign was never in view."""
    report = texture_eval.TextureReport(sign)
    for camera in texture_eval.CAMERAS:
        report.conf_at_m[camera] = {p: {d: float("nan") for d in texture_eval.FIXED_DISTANCES_M} for p in placements}
        report.detection_rate[camera] = {p: float("nan") for p in placements}
        report.first_detection_m[camera] = {p: None for p in placements}
        report.drive_by[camera] = {p: [] for p in placements}
    return report


def _record_each_stage(monkeypatch, what, measure: bool = True) -> list:
    """Fakes the drive-bys and the figure, and the fixed-distance tables unless `measure`, and returns the list to
    which each stage appends (stage, what(its base config))."""
    seen = []
    real_evaluate = texture_eval.evaluate_texture

    def fake_evaluate(sign, town, placements, threshold, base=None, detector="detector"):
        seen.append(("fixed distances", what(base)))
        if not measure:
            return _empty_report(sign, placements)
        return real_evaluate(sign, town, placements, threshold, base=base, detector=detector)

    def fake_drive_by(sign, detector, town, placement, drives, base=None):
        seen.append(("drive-bys", what(base)))
        return disappearance.DriveBys(sign, detector, town, placement, base.policy.conf_threshold, base.policy.trigger_dist_m)

    def fake_grid(signs, out_path, town="town07", base=None, detector="detector"):
        seen.append(("figure", what(base)))
        Path(out_path).write_bytes(b"")
        return Path(out_path)

    monkeypatch.setattr(texture_eval, "evaluate_texture", fake_evaluate)
    monkeypatch.setattr(texture_eval, "fig3_grid", fake_grid)
    monkeypatch.setattr(disappearance, "drive_by_frames", fake_drive_by)
    return seen


STAGES = ("fixed distances", "drive-bys", "figure")


# One measurement with both flags: the fixed-distance tables run for real (about 17 CPU-s), and each flag reaches
# every stage on its own path (the render setting into the scenario, the weights into the perception).
@pytest.mark.slow
def test_attack_eval_draws_every_frame_under_the_setting_scores_it_with_the_named_weights_and_names_both(
        tmp_path, monkeypatch):
    weights = "models/sign_detector_scenes.pt"
    seen = _record_each_stage(monkeypatch, lambda base: (base.scenario.materials, base.scenario.foliage,
                                                         base.perception.weights_path))
    out = tmp_path / "eval"
    assert cli.main(["attack", "eval", "--signs", "clean", "--placements", "standard", "--drives", "1",
                     "--setting", "textured_clusters", "--weights", weights, "--out", str(out)]) == 0
    assert seen == [(stage, ("textured", "clusters", weights)) for stage in STAGES]
    report = (out / "report.md").read_text()
    assert "Render setting: `textured_clusters` (scenario.materials=textured, scenario.foliage=clusters)" in report
    assert f"The own detector ({weights}) on full 640x480 frames" in report


def test_attack_eval_set_values_reach_every_stage_beside_the_setting_and_the_report_names_them(tmp_path, monkeypatch):
    seen = _record_each_stage(monkeypatch, lambda base: (base.scenario.materials, base.scenario.fog_end_m,
                                                         base.camera.fovy_deg, base.policy.conf_threshold),
                              measure=False)
    out = tmp_path / "eval"
    assert cli.main(["attack", "eval", "--signs", "clean", "--placements", "standard", "--drives", "1", "--setting",
                     "textured", "--set", "scenario.fog_end_m=300", "--set", "camera.fovy_deg=40", "--set",
                     "policy.conf_threshold=0.6", "--out", str(out)]) == 0
    assert seen == [(stage, ("textured", 300.0, 40.0, 0.6)) for stage in STAGES]
    report = (out / "report.md").read_text()
    assert ("Every frame drawn with --set camera.fovy_deg=40 --set policy.conf_threshold=0.6 --set "
            "scenario.fog_end_m=300, beside the setting's own values.") in report
    assert "Threshold for detection rate and first detection: 0.6." in report
