"""`avsim attack generate`: the budget on the saved PNG, sticker areas at full size, targets, and
regeneration from a texture's JSON record (`--from`)."""

import json

import pytest
import torch

from avsim import cli
from avsim.attacks.budget import ssim
from avsim.attacks.eykholt import sticker_mask
from avsim.attacks.generate import (apply_change, clean_stop_texture, downsample, face_mask_full, generate,
                                    generate_from, prepare, read_recipe, texture_tensor, within_budget_on_disk)
from avsim.attacks.photometric import CLOSED_LOOP_PHOTOMETRIC
from avsim.attacks.view_bank import ViewBankSpec, closed_loop_bank_spec
from avsim.errors import ConfigError
from avsim.world.textures import TEXTURE_DIR

TINY_BANK = ViewBankSpec(towns=("town07",), placements=("standard",), lightings_per_cell=1, views_per_group=3,
                         dist_range_m=(15.0, 40.0), seed=3)


@pytest.fixture(scope="module")
def clean():
    full = clean_stop_texture()
    return texture_tensor(full), downsample(full)


@pytest.mark.parametrize("fraction", [0.05, 0.12, 0.2])
def test_a_sticker_budget_holds_on_the_full_size_texture_with_zero_tolerance(clean, fraction):
    clean_full, clean_small = clean
    face_small = face_mask_full(*clean_small.shape[-2:])
    mask = sticker_mask(face_small, 4, fraction, torch.Generator().manual_seed(0))
    # Sticker colours far from the sign's, so every sticker texel really changes.
    attacked = clean_small * (1 - mask) + torch.tensor([0.1, 0.9, 0.2]).view(3, 1, 1) * mask
    full = apply_change(clean_full, clean_small, attacked, mask, fraction)
    rgb = (full * 255).round() / 255
    face = face_mask_full(*clean_full.shape[-2:])
    changed = (rgb - clean_full).abs().amax(dim=0) > 0
    assert float(changed.sum()) <= fraction * float(face.sum())
    assert not bool(changed[face[0] == 0].any())
    # Bilinear upsampling, the old way, spread the bars past their budget.
    spread = apply_change(clean_full, clean_small, attacked)
    spread_changed = ((spread * 255).round() / 255 - clean_full).abs().amax(dim=0) > 0
    assert float(spread_changed.sum()) > float(changed.sum())


def test_the_ssim_floor_is_met_on_the_8_bit_png(clean):
    clean_full, _ = clean
    noise = torch.randn(clean_full.shape, generator=torch.Generator().manual_seed(1)) * 0.25
    attacked = (clean_full + noise * face_mask_full(*clean_full.shape[-2:])).clamp(0, 1)
    face = face_mask_full(*clean_full.shape[-2:])
    assert ssim(attacked, clean_full, face) < 0.5
    rgb = within_budget_on_disk(clean_full, attacked, 0.7)
    measured = ssim(texture_tensor(rgb), clean_full, face)
    assert 0.7 <= measured < 0.72  # scaled back only as far as needed


def test_a_texture_regenerates_from_its_record_bit_for_bit(tmp_path, clean):
    setup = prepare(bank_spec=TINY_BANK)
    first = tmp_path / "first.png"
    _, record = generate("lu_v2", first, setup=setup, hyperparameters={"steps": 2, "views_per_step": 2}, seed=5,
                         progress=False)
    assert record["detector"] == "detector" and "sign_detector.pt" in record["weights_sha256"]
    assert record["view_bank"]["views"] == len(setup.scene.bank) and record["cpu_seconds"] > 0
    assert record["torch_cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    recipe = read_recipe(first.with_suffix(".json"))
    assert recipe.bank_spec == TINY_BANK and recipe.seed == 5 and recipe.threads == record["torch_threads"]
    second = tmp_path / "second.png"
    generate_from(first.with_suffix(".json"), second, progress=False)
    assert first.read_bytes() == second.read_bytes()


def test_closed_loop_methods_get_the_closed_loop_bank_and_sensor():
    from avsim.attacks.generate import default_bank

    spec, photometric = default_bank("driveby", ("front", "side"), 60.0)
    assert spec.frame_spacing_m == pytest.approx(60 / 3.6 * 0.05, abs=1e-4) and spec.cameras == ("front", "side")
    assert photometric == CLOSED_LOOP_PHOTOMETRIC
    assert default_bank("yang", ("front",), 85.0)[0] == ViewBankSpec()
    assert closed_loop_bank_spec().braking_probability > 0


def test_a_record_from_elsewhere_is_refused_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"method": "lu_v2"}))
    with pytest.raises(ConfigError, match="not a texture record .* has no 'seed' field"):
        read_recipe(bad)
    code = cli.main(["attack", "generate", "--from", str(bad), "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "not a texture record" in err[0]
    assert not (tmp_path / "x.png").exists()


def test_a_record_from_before_the_rework_says_it_cannot_be_replayed(tmp_path, capsys):
    # A record written before the drive-by rework names no weights_sha256 and takes hyperparameters
    # today's attacks no longer do (yang's mean_bound): --from says the generator is gone instead of
    # failing on the hyperparameter. Every shipped texture has today's record; users may hold old ones.
    record = json.loads((TEXTURE_DIR / "yang.json").read_text())
    record.pop("weights_sha256")
    record["hyperparameters"]["mean_bound"] = record.pop("derived")["mean_bound"]
    old = tmp_path / "records" / "old_yang.json"
    old.parent.mkdir()
    old.write_text(json.dumps(record))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    code = cli.main(["attack", "generate", "--from", str(old), "--out", str(out_dir / "x.png")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "before the drive-by rework" in err[0]
    assert list(out_dir.iterdir()) == []


# A shipped record with one field changed: each is refused by `--from` before anything renders, naming the field.
BAD_RECORD_FIELDS = [
    (("weights_sha256",), "abc", "weights_sha256"),
    (("weights_sha256",), None, "weights_sha256"),
    (("hyperparameters",), "abc", "hyperparameters must be a table"),
    (("purify",), "jpeg", "purify must be a table"),
    (("view_bank",), [], "view_bank must be a table"),
    (("view_bank", "seed"), -5, "view bank seed"),
    (("view_bank", "towns"), [], "view bank towns"),
    (("view_bank", "towns"), ["town99"], "view bank towns"),
    (("view_bank", "placements"), ["diagonal"], "view bank placements"),
    (("view_bank", "cameras"), "front", "view bank cameras"),
    (("view_bank", "lightings_per_cell"), 0, "view bank lightings_per_cell"),
    (("view_bank", "lightings_per_cell"), "2", "view bank lightings_per_cell"),
    (("view_bank", "views_per_group"), 2.5, "view bank views_per_group"),
    (("view_bank", "dist_range_m"), [500, 600], "view bank dist_range_m"),
    (("view_bank", "dist_range_m"), [60, 10], "lo <= hi"),
    (("view_bank", "lateral_jitter_m"), -3, "view bank lateral_jitter_m"),
    (("view_bank", "fog_probability"), 5, "view bank fog_probability"),
    (("view_bank", "sun_elevation_deg"), [75, 500], "view bank sun_elevation_deg"),
    (("view_bank", "sun_intensity"), [-1, -0.5], "view bank sun_intensity"),
    (("photometric", "gain"), [1.3, -0.7], "photometric gain"),
    (("photometric", "gain"), [0.7, 1.0, 1.3], "photometric gain must be a pair"),
    (("photometric", "blur_probability"), 5, "photometric blur_probability"),
    (("photometric", "jpeg_quality"), [0, 500], "photometric jpeg_quality"),
    (("photometric", "noise_std"), [-1, -0.5], "photometric noise_std"),
    (("photometric", "motion_blur_kernel_px"), 0, "photometric motion_blur_kernel_px"),
    (("photometric", "motion_blur_kernel_px"), 4, "must be odd"),
    (("photometric", "quantise_8bit"), "yes", "photometric quantise_8bit"),
]


@pytest.mark.parametrize("path, value, named", BAD_RECORD_FIELDS, ids=lambda v: str(v) if isinstance(v, tuple) else None)
def test_a_record_field_of_the_wrong_shape_or_out_of_range_is_refused_naming_it(tmp_path, path, value, named):
    record = json.loads((TEXTURE_DIR / "yang.json").read_text())
    *parents, leaf = path
    table = record
    for key in parents:
        table = table[key]
    table[leaf] = value
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(record))
    with pytest.raises(ConfigError) as refused:
        read_recipe(bad)
    message = str(refused.value)
    assert "\n" not in message and message.startswith(f"--from {bad}") and named in message, message


def test_every_shipped_record_is_written_by_todays_generator():
    assert [p.name for p in TEXTURE_DIR.glob("*.json") if "weights_sha256" not in json.loads(p.read_text())] == []


@pytest.mark.parametrize("argv, mention", [
    (["--from", "textures/yang.json", "--method", "yang"], "drop --method"),
    (["--method", "driveby", "--detector", "yolo9000"], "--detector"),
    (["--method", "driveby", "--ssim-floor", "1.5"], "--ssim-floor"),
    (["--steps", "3"], "--method"),
    (["--from", "textures/yang.json", "--threads", "4"], "drop --threads"),
    (["--from", "textures/driveby_detector.json", "--speed-kmh", "50"], "drop --speed-kmh"),
    (["--method", "yang", "--speed-kmh", "50"], "random distances"),
])
def test_generate_flags_are_checked_before_any_work(tmp_path, capsys, argv, mention):
    code = cli.main(["attack", "generate", *argv, "--out", str(tmp_path / "t.png")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and mention in err[0]
    assert list(tmp_path.iterdir()) == []


def test_the_texture_record_names_every_weight_file_of_the_ensemble():
    from avsim.attacks.targets import build_target

    hashes = build_target("ensemble").weight_hashes()
    assert set(hashes) == {"sign_detector.pt", "centernet.json", "centernet.bin"}
    assert all(len(digest) == 64 for digest in hashes.values())


def test_the_three_network_target_names_every_weight_file_and_a_regeneration_checks_them(monkeypatch):
    from avsim.attacks import generate
    from avsim.attacks.targets import build_target

    hashes = build_target("ensemble_all").weight_hashes()
    assert set(hashes) == {"sign_detector.pt", "centernet.json", "centernet.bin", "yolov3-tiny.cfg",
                           "yolov3-tiny.weights", "coco.names"}
    assert build_target("ensemble_all_2of3").weight_hashes() == hashes
    recipe = type("Recipe", (), {"detector": "yolo", "weight_hashes": {**hashes, "yolov3-tiny.weights": "0" * 64}})()
    with pytest.raises(ConfigError, match="yolov3-tiny.weights"):
        generate.check_weights(recipe)
    recipe.weight_hashes = hashes
    generate.check_weights(recipe)


def test_attack_eval_takes_yolo_among_its_detectors_and_refuses_others_in_one_line(capsys):
    assert cli.main(["attack", "eval", "--detectors", "detector,yolo,onnx", "--signs", "clean"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "--detectors: unknown name 'onnx'; choose from detector, coco, yolo, nanodet" in err[0]


def test_an_unknown_purification_is_one_line_and_exit_2_before_anything_is_rendered(tmp_path, capsys):
    out = tmp_path / "t.png"
    assert cli.main(["attack", "generate", "--method", "driveby", "--purify", "gzip", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--purify gzip" in err and "jpeg, median" in err and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
