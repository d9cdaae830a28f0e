"""Sign materials (`scenario.sign_materials = "sheeting"`): the standard's sheeting colours, the aluminium
blank and the galvanised post; the default signs unchanged; a user's texture kept as it is."""

import cv2
import numpy as np
import pytest

from avsim.errors import ConfigError
from avsim.config import ScenarioConfig
from avsim.world import sign_materials as sm
from avsim.world.scene import compose_scene
from avsim.world.textures import RED, WHITE, save_texture_png
from helpers import make_config


def _xyY(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    """CIE 1931 (x, y, Y) of an 8-bit sRGB colour: the inverse of `srgb_from_xyY`, by OpenCV's matrix."""
    encoded = np.float32(rgb) / 255
    linear = np.where(encoded <= 0.04045, encoded / 12.92, ((encoded + 0.055) / 1.055) ** 2.4).astype(np.float32)
    x, y, z = cv2.cvtColor(linear[None, None], cv2.COLOR_RGB2XYZ)[0, 0]
    return x / (x + y + z), y / (x + y + z), y


def _inside(box_xy, x: float, y: float) -> bool:
    return cv2.pointPolygonTest(np.float32(box_xy), (float(x), float(y)), False) > 0


def test_the_sheeting_colours_lie_in_the_standards_boxes_at_their_luminance_factors():
    red_x, red_y, red_luminance = _xyY(sm.SHEETING_PALETTE.red)
    white_x, white_y, white_luminance = _xyY(sm.SHEETING_PALETTE.white)
    assert _inside(sm.RED_BOX_XY, red_x, red_y) and 0.025 <= red_luminance <= 0.15
    assert _inside(sm.WHITE_BOX_XY, white_x, white_y) and white_luminance >= 0.27
    # White is at its stated Y and the box's mean; red moved a little by clipping to the sRGB gamut.
    assert white_luminance == pytest.approx(sm.WHITE_LUMINANCE_FACTOR, abs=0.005)
    assert (white_x, white_y) == pytest.approx(sm.box_mean(sm.WHITE_BOX_XY), abs=0.003)
    assert red_luminance == pytest.approx(sm.RED_LUMINANCE_FACTOR, abs=0.01)
    # The design colours are not in the boxes' luminance: paper white is far above the sheeting's.
    assert _xyY(WHITE)[2] > 0.99 and not _inside(sm.RED_BOX_XY, *_xyY(RED)[:2])


def test_a_sheeting_face_is_the_design_face_in_the_sheeting_colours():
    face = sm.sheeting_face("stop_sign")
    colours, counts = np.unique(face.reshape(-1, 3), axis=0, return_counts=True)
    top_two = {tuple(int(v) for v in c) for c in colours[np.argsort(counts)[-3:]]} - {(128, 128, 128)}
    assert top_two == {sm.SHEETING_PALETTE.red, sm.SHEETING_PALETTE.white}
    assert not (face == np.uint8(RED)).all(axis=2).any()
    assert not face.flags.writeable  # shared between scenes


def _geom(spec, name):
    return next((g for g in spec.geoms if g.name == name), None)


def test_sheeting_mounts_the_signs_on_an_aluminium_blank_and_a_galvanised_post():
    spec, info = compose_scene(make_config(scenario={"sign_materials": "sheeting"}))
    for sign in info.signs:
        assert _geom(spec, f"{sign.name}/blank").material == sm.ALUMINIUM
        assert _geom(spec, f"{sign.name}/post").material == sm.GALVANISED
    texture = spec.texture(info.stop_sign.texture_name)
    assert bytes(texture.data) == sm.sheeting_face("stop_sign").tobytes()
    default, info = compose_scene(make_config())
    assert _geom(default, f"{info.stop_sign.name}/blank") is None and _geom(default, f"{info.stop_sign.name}/post").material == ""


def test_a_user_texture_keeps_its_pixels_under_sheeting(tmp_path):
    blue = np.zeros((64, 64, 3), np.uint8)
    blue[..., 2] = 230
    save_texture_png(tmp_path / "blue.png", blue)
    spec, info = compose_scene(make_config(scenario={"sign_materials": "sheeting", "sign": str(tmp_path / "blue.png")}))
    assert bytes(spec.texture(info.stop_sign.texture_name).data) == blue.tobytes()


@pytest.mark.parametrize("key, value", [("sign_materials", "glossy"), ("sun_shadow_map_px", 3000), ("sun_shadow_map_px", 4096.0)])
def test_sign_materials_and_shadow_map_sizes_are_named_choices(key, value):
    with pytest.raises(ConfigError, match=f"scenario.{key}"):
        ScenarioConfig(**{key: value})
