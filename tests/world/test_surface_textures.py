"""Procedural surface textures: fixed by their seed, the flat colours on average, detail at the texel scale."""

import hashlib

import numpy as np
import pytest

from avsim.config import ScenarioConfig
from avsim.errors import ConfigError
from avsim.world import props, surface_textures


@pytest.fixture(scope="module")
def ground():
    return surface_textures.ground_textures(props._FLAT_COLOURS)


def test_textures_are_the_same_every_time(ground):
    again = surface_textures.ground_textures(props._FLAT_COLOURS)
    assert all(np.array_equal(ground[name], again[name]) for name in ground)
    facades = surface_textures.facade_textures(props.FACADE_COLOURS)
    assert all(np.array_equal(a, b) for a, b in zip(facades.values(), surface_textures.facade_textures(props.FACADE_COLOURS).values()))


def test_each_texture_keeps_its_flat_colour_on_average_and_varies_at_the_texel_scale(ground):
    for name, texture in ground.items():
        mean = texture.reshape(-1, 3).mean(axis=0) / 255
        # Within 7 levels of 255: clipping of the brightest texels (wheat) moves the mean a little.
        assert np.abs(mean - np.asarray(props._FLAT_COLOURS[name])).max() < 0.028, name
        neighbour_step = np.abs(np.diff(texture.astype(float), axis=1)).mean()
        assert neighbour_step > 2.0, name  # detail from texel to texel, not one colour


def test_a_facade_texture_has_a_window_darker_than_its_wall():
    brick = surface_textures.facade_textures(props.FACADE_COLOURS)["facade_brick"].astype(float)
    assert brick.shape == (350, 250, 3)
    assert brick[150:200, 70:110].mean() < 0.7 * brick[10:60, 10:40].mean()


def test_materials_is_a_named_choice():
    assert ScenarioConfig().materials == "flat"
    with pytest.raises(ConfigError, match="scenario.materials"):
        ScenarioConfig(materials="shiny")


def _worn(beneath: np.ndarray) -> np.ndarray:
    return surface_textures.worn_paint(np.random.default_rng(5), props._FLAT_COLOURS["paint_white"], beneath)


def test_worn_paint_keeps_its_share_of_paint_and_shows_the_surface_beneath_elsewhere(ground):
    worn = _worn(ground["asphalt"]).astype(float)
    paint = np.asarray(props._FLAT_COLOURS["paint_white"]) * 255
    nearer_paint = np.linalg.norm(worn - paint, axis=2) < np.linalg.norm(worn - ground["asphalt"].astype(float), axis=2)
    assert abs(nearer_paint.mean() - surface_textures.PAINT_RETAINED_FRACTION) < 0.03
    # Where the paint is gone, the texels are the asphalt's own (its grain and stones show through).
    gone = ~nearer_paint
    assert np.abs(worn[gone] - ground["asphalt"][gone]).mean() < 25
    assert np.array_equal(worn, _worn(ground["asphalt"]).astype(float))


def test_road_paint_is_a_named_choice_and_fresh_paint_is_flat():
    assert ScenarioConfig().road_paint == "fresh"
    with pytest.raises(ConfigError, match="scenario.road_paint"):
        ScenarioConfig(road_paint="faded")


def test_worn_paint_gives_the_paint_materials_a_texture_and_leaves_the_others_alone():
    import mujoco

    def model(worn_paint: bool) -> mujoco.MjModel:
        spec = mujoco.MjSpec()
        props.add_materials(spec, worn_paint=worn_paint)
        return spec.compile()

    fresh, worn = model(False), model(True)
    for name in props.PAINTS:
        assert fresh.mat_texid[fresh.material(name).id].max() == -1
        assert worn.mat_texid[worn.material(name).id].max() >= 0
    assert fresh.nmat == worn.nmat
    for name in ("asphalt", "grass", "facade_brick"):
        assert np.array_equal(fresh.mat_rgba[fresh.material(name).id], worn.mat_rgba[worn.material(name).id])


def test_the_windowed_facade_textures_are_what_they_were_before_the_window_constants_were_shared():
    """`facade` draws its window from the constants that `facade_windows` builds geometry from (2026-12-07);
    the textures must stay the ones every `textured` result was measured on (sha256 at 3585995)."""
    textures = surface_textures.facade_textures(props.FACADE_COLOURS)
    digests = {name: hashlib.sha256(rgb.tobytes()).hexdigest()[:12] for name, rgb in textures.items()}
    assert digests == {"facade_brick": "76aa3ee68051", "facade_concrete": "5d260ff5ca4d",
                       "facade_glass": "199693552ce2", "facade_sand": "82e33dfa470e"}
