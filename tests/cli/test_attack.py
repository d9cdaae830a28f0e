"""`avsim attack eval --setting` and `--weights`: every frame of the measurement is drawn under the named render
setting, and scored by the named weights."""

from pathlib import Path

import pytest

import avsim.experiments.attacks.disappearance as disappearance
import avsim.experiments.attacks.texture_eval as texture_eval
from avsim import cli


def _record_each_stage(monkeypatch, what) -> list:
    """Fakes the drive-bys and the figure (the fixed-distance tables still run), and returns the list to which
    each stage appends (stage, what(its base config))."""
    seen = []
    real_evaluate = texture_eval.evaluate_texture

    def fake_evaluate(sign, town, placements, threshold, base=None, detector="detector"):
        seen.append(("fixed distances", what(base)))
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
