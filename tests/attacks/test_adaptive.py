"""The adaptive attacker: a texture optimised over the front and the side camera's views
(`avsim attack generate --cameras front,side`), shipped as textures/adaptive.png."""

import json

import pytest

from avsim import cli
from avsim.attacks.budget import SSIM_FLOOR
from avsim.attacks.generate import clean_stop_texture, downsample
from avsim.attacks.view_bank import CROP_PX, ViewBankSpec, build_view_bank
from avsim.errors import ConfigError
from avsim.world.textures import TEXTURE_DIR


@pytest.mark.parametrize("cameras", ["front,rear", "front,front", ","])
def test_generate_rejects_bad_cameras_with_exit_2_and_writes_nothing(tmp_path, capsys, cameras):
    out = tmp_path / "adaptive.png"
    code = cli.main(["attack", "generate", "--method", "yang", "--cameras", cameras, "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "cameras" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_view_bank_spec_names_real_cameras():
    with pytest.raises(ConfigError, match="rear"):
        ViewBankSpec(cameras=("front", "rear"))


def test_a_two_camera_bank_holds_side_views_with_the_sign_in_the_crop():
    spec = ViewBankSpec(towns=("town07",), placements=("standard",), cameras=("front", "side"), lightings_per_cell=1,
                        views_per_group=6, seed=1)
    bank = build_view_bank(spec, downsample(clean_stop_texture()))
    side = [i for i in range(len(bank)) if bank.camera[i] == "side"]
    # Every drive-by distance the front camera keeps, the side camera keeps too (10-60 m).
    assert len(side) == bank.camera.count("front") == spec.views_per_group
    assert min(bank.dist_m[i] for i in side) < 20 and max(bank.dist_m[i] for i in side) > 50
    for i in side:
        x0, y0, x1, y1 = bank.sign_box_px[i].tolist()
        assert 0 <= x0 < x1 <= CROP_PX and 0 <= y0 < y1 <= CROP_PX, (bank.dist_m[i], (x0, y0, x1, y1))
    # A group is one camera's drive-by, so sequence sampling never mixes the cameras.
    assert all(len({bank.camera[i] for i in group}) == 1 for group in bank.groups)


def test_shipped_adaptive_texture_was_optimised_over_both_cameras_within_the_budget():
    record = json.loads((TEXTURE_DIR / "adaptive.json").read_text())
    bank = record["view_bank"]
    assert bank["cameras"] == ["front", "side"]
    assert bank["views_by_camera"]["side"] >= 100 and bank["views_by_camera"]["front"] >= 100
    assert record["ssim"] >= SSIM_FLOOR  # the PNG itself: test_attacks.py's shipped-texture budget test
