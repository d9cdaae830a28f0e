"""The closed-loop view bank: drive-by spacing, the braking gate's geometry, pitch, and the
experiment files' lighting; and the EOT scene's windowed warp."""

import math
import tomllib
from pathlib import Path

import pytest
import torch

from avsim.attacks.eot import EotScene
from avsim.attacks.generate import clean_stop_texture, downsample, load_detector
from avsim.attacks.view_bank import CLOSED_LOOP_FOG_PROBABILITY, CLOSED_LOOP_LIGHTING, ViewBankSpec, frame_spacing_m
from avsim.attacks.warp import composite, warp_texture
from avsim.errors import ConfigError

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


@pytest.fixture(scope="module")
def bank(drive_by_bank):
    return drive_by_bank


def test_a_drive_by_group_is_every_frame_at_the_loops_spacing(bank):
    assert frame_spacing_m(85.0, 0.05) == pytest.approx(1.1806, abs=1e-4)
    (group,) = bank.groups
    dists = [bank.dist_m[i] for i in group]
    steps = [a - b for a, b in zip(dists, dists[1:])]
    assert all(step == pytest.approx(1.1806, abs=1e-3) for step in steps)
    assert 48.8 < dists[0] <= 50.0 and dists[-1] < 12.0  # beyond the 40 m gate, down to where the sign leaves


def test_the_gate_estimate_of_a_true_box_is_the_true_distance_to_the_stop_line(bank):
    views = torch.arange(len(bank))
    estimate = bank.stop_line_estimate_m(views, bank.true_height_px)
    truth = torch.tensor(bank.dist_m) - 1.0  # the stop line is 1 m before the sign
    # The box of the texture square is the octagon's; lateral offset and yaw jitter move it a little.
    assert torch.allclose(estimate, truth, atol=0.35 + 0.01 * truth.max())
    # A box 20 % short reads 25 % farther from the camera.
    short = bank.stop_line_estimate_m(views, 0.8 * bank.true_height_px)
    ahead = bank.gate_ahead_m
    assert torch.allclose(short + bank.gate_offset_m, 1.25 * ahead, rtol=1e-5)


def test_about_half_the_views_are_posed_with_the_braking_pitch(bank):
    pitched = [p for p in bank.pitch_deg if p > 0]
    assert 0.25 * len(bank) < len(pitched) < 0.75 * len(bank)
    assert max(bank.pitch_deg) <= 2.5 and min(bank.pitch_deg) >= 0.0


def test_the_closed_loop_bank_covers_every_experiment_files_lighting():
    for path in sorted(EXPERIMENTS.rglob("*.toml")):
        data = tomllib.loads(path.read_text())
        vary = data.get("vary", {}).get("scenario", {})
        for key, (low, high) in vary.items():
            assert key in CLOSED_LOOP_LIGHTING, (path.name, key)
            bank_low, bank_high = CLOSED_LOOP_LIGHTING[key]
            assert bank_low <= low and high <= bank_high, (path.name, key)
        scenarios = [data.get("defaults", {}).get("scenario", {})] + [c.get("scenario", {}) for c in data.get("cells", [])]
        if any(s.get("fog_end_m", 0) for s in scenarios):
            assert CLOSED_LOOP_FOG_PROBABILITY > 0, f"{path.name} has fog; the closed-loop bank has none"


def test_bad_drive_by_specs_are_refused_before_rendering():
    with pytest.raises(ConfigError, match="frame_spacing_m"):
        ViewBankSpec(frame_spacing_m=0.0)
    with pytest.raises(ConfigError, match="dist_range_m"):
        ViewBankSpec(dist_range_m=(50.0, 10.0))


def test_the_windowed_warp_equals_the_whole_crop_warp(bank):
    detector, _ = load_detector()
    scene = EotScene(bank, detector)
    texture = downsample(clean_stop_texture())
    texture = (texture + 0.2 * torch.rand(texture.shape, generator=torch.Generator().manual_seed(0))).clamp(0, 1)
    views = list(range(0, len(bank), 5))
    windowed = scene.images(texture, views, torch.Generator(), photometric=False)
    idx = torch.as_tensor(views)
    warped, mask = warp_texture(texture, bank.alpha, bank.corners_px[idx], tuple(bank.backgrounds.shape[-2:]))
    whole = composite(warped, mask, bank.backgrounds[idx].float() / 255, bank.gain[idx], bank.offset[idx])
    assert (windowed - whole).abs().max() < 1e-5
    assert math.isclose(float((windowed - whole).abs().mean()), 0.0, abs_tol=1e-7)
