"""Attack families: registry, budgets, and a short optimisation that must lower the detector's score."""

import json

import numpy as np
import pytest
import torch

from avsim import cli
from avsim.attacks.budget import SSIM_FLOOR, linf, project_linf, ssim
from avsim.attacks.eot import EotScene
from avsim.attacks.generate import downsample, load_detector, texture_tensor
from avsim.attacks.registry import ATTACKS
from avsim.attacks.sign_view import face_alpha
from avsim.attacks.view_bank import ViewBankSpec, build_view_bank
from avsim.world.signs import SIGN_SHAPES
from avsim.world.textures import TEXTURE_DIR, load_texture_png

# The five study families (each shipped as textures/NAME.png) and the closed-loop ones of issue 14.
SHIPPED_ATTACKS = ["chen", "eykholt", "lu_v2", "lu_v3", "yang"]
CLOSED_LOOP_ATTACKS = ["driveby", "range_inflation"]
# Every attacked texture in textures/ has its JSON record beside it.
SHIPPED_TEXTURES = sorted(p.stem for p in TEXTURE_DIR.glob("*.json"))


@pytest.fixture(scope="module")
def clean_small():
    return downsample(load_texture_png(TEXTURE_DIR / "stop_sign.png"))


@pytest.fixture(scope="module")
def small_scene(clean_small):
    spec = ViewBankSpec(towns=("town07",), placements=("standard",), lightings_per_cell=1, views_per_group=8,
                        dist_range_m=(12.0, 40.0), seed=1)
    detector, _ = load_detector()
    return EotScene(build_view_bank(spec, clean_small), detector)


def test_every_attack_is_registered_and_cites_its_paper():
    assert ATTACKS.names() == sorted(SHIPPED_ATTACKS + CLOSED_LOOP_ATTACKS)
    for name in ATTACKS.names():
        attack_class = ATTACKS.get(name)
        assert attack_class.paper
        module_doc = __import__(attack_class.__module__, fromlist=["_"]).__doc__
        assert "Paper" in module_doc and "Objective" in module_doc and "Constraint" in module_doc


def test_linf_projection_keeps_the_bound_the_face_and_the_colour_range():
    gen = torch.Generator().manual_seed(0)
    clean = torch.rand(3, 16, 16, generator=gen)
    mask = torch.zeros(1, 16, 16)
    mask[:, 4:12, 4:12] = 1
    delta = project_linf(torch.randn(3, 16, 16, generator=gen), 0.1, clean, mask)
    assert delta.abs().max() <= 0.1 + 1e-6
    assert torch.all(delta[:, mask[0] == 0] == 0)
    assert torch.all((clean + delta >= 0) & (clean + delta <= 1))


def test_ssim_is_one_for_the_same_texture_and_lower_for_noise(clean_small):
    noisy = (clean_small + 0.3 * torch.randn(clean_small.shape, generator=torch.Generator().manual_seed(0))).clamp(0, 1)
    assert ssim(clean_small, clean_small) == pytest.approx(1.0, abs=1e-4)
    assert ssim(noisy, clean_small) < 0.5


@pytest.mark.parametrize("method", SHIPPED_ATTACKS)
def test_a_short_optimisation_lowers_the_score_on_held_out_views(small_scene, clean_small, method):
    attack = ATTACKS.get(method)(small_scene, steps=10, views_per_step=4, lr=0.03, seed=0)
    result = attack(clean_small)
    # Held out: fresh views and photometric draws from a seed the attack never used.
    clean_score = small_scene.evidence(clean_small, 16, torch.Generator().manual_seed(123)).score.mean()
    attacked_score = small_scene.evidence(result.texture, 16, torch.Generator().manual_seed(123)).score.mean()
    assert attacked_score < clean_score
    assert len(result.loss_history) == 10 and all(np.isfinite(result.loss_history))


def test_same_seed_same_texture(small_scene, clean_small):
    first = ATTACKS.get("lu_v2")(small_scene, steps=3, views_per_step=2, seed=4)(clean_small).texture
    second = ATTACKS.get("lu_v2")(small_scene, steps=3, views_per_step=2, seed=4)(clean_small).texture
    assert torch.equal(first, second)


@pytest.mark.parametrize("name", SHIPPED_TEXTURES)
def test_shipped_textures_keep_their_budget_on_the_png(name):
    png, record_path = TEXTURE_DIR / f"{name}.png", TEXTURE_DIR / f"{name}.json"
    record = json.loads(record_path.read_text())
    clean = texture_tensor(load_texture_png(TEXTURE_DIR / "stop_sign.png"))
    attacked = texture_tensor(load_texture_png(png))
    face = (face_alpha(SIGN_SHAPES["stop_sign"], *clean.shape[-2:]) > 0.5).float()
    measured_ssim = ssim(attacked, clean, face)
    assert measured_ssim >= max(SSIM_FLOOR, record.get("ssim_floor", SSIM_FLOOR))
    assert measured_ssim == pytest.approx(record["ssim"], abs=1e-4)
    # Nothing changes off the sign face.
    assert torch.all(attacked[:, face[0] == 0] == clean[:, face[0] == 0])
    hyper = record["hyperparameters"]
    bound = hyper.get("eps", hyper.get("eps_peak"))
    if bound is not None:
        assert linf(attacked, clean) <= bound + 0.5 / 255  # 8-bit rounding
    if "max_area_fraction" in hyper:  # stickers: the changed area is within its bound, with zero tolerance
        changed = (attacked - clean).abs().amax(dim=0) > 0
        assert float(changed.sum()) <= hyper["max_area_fraction"] * float(face.sum())


@pytest.mark.parametrize("content, mention", [(b"not a png at all", "not a PNG"), (None, "does not exist")],
                         ids=["not_png", "missing"])
def test_bad_sign_textures_exit_2_with_one_line(tmp_path, capsys, content, mention):
    path = tmp_path / "sign.png"
    if content is not None:
        path.write_bytes(content)
    code = cli.main(["run", "--perception", "oracle", "--sign", str(path)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and mention in err[0]


def test_wrong_shape_texture_exits_2(tmp_path, capsys):
    import cv2

    path = tmp_path / "wide.png"
    cv2.imwrite(str(path), np.zeros((64, 256, 3), np.uint8))
    code = cli.main(["run", "--perception", "oracle", "--sign", str(path)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "wide.png" in err[0]


@pytest.mark.slow  # two study runs with the detector (about 25 CPU-s): a finding, beside the study's outcomes
def test_the_strongest_shipped_attack_against_baseline_in_town07(study_run):
    # With the rigid car yang delayed the first detection at seed 0 from 39.6 m to 34.9 m and
    # baseline ran 0.8 m past. With the suspended car (the body squats 0.04 deg at cruise and the
    # frames fall elsewhere along the approach) the detector scores one attacked frame above 0.5
    # as soon as the box reaches the perception's 16 px range, as for the clean sign, and 0.85
    # brake now gives 8.0 m/s^2: the attack changes nothing at this seed. Asserted as the
    # finding it is (issue 12 re-measures it over seeds without the range cut).
    clean = study_run("town07", "standard", "baseline", perception="detector")
    attacked = study_run("town07", "standard", "baseline", perception="detector", sign="yang")
    assert clean.sign_margin_m > 0
    assert attacked.sign_margin_m > 0
    frame_spacing_m = 85 / 3.6 * 0.05
    assert abs(attacked.first_detection_dist_m - clean.first_detection_dist_m) <= frame_spacing_m
