"""Clouds over the daylight sky: the cover is the oktas asked for, the clear patches are the clear sky's
own, the light follows the two-stream physics, the contrast fades with distance, and the field is seeded."""

import math

import mujoco
import numpy as np
import pytest

from avsim.config import ScenarioConfig, SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.world import clouds, sky
from avsim.world.scene import build_scene

TEXELS = 64  # small faces keep these tests fast; the cover and the physics do not depend on the size
SUN = sky.sun_direction(50.0, 30.0)
DEFAULTS = ScenarioConfig()
BASE_M, VISIBILITY_M = DEFAULTS.cloud_base_m, DEFAULTS.cloud_visibility_km * 1000.0


def _optical_depth(oktas: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(tau, solid-angle weights above the horizon) of the texels of a TEXELS skybox, as the sky draws them."""
    directions = sky.cube_directions(TEXELS)
    x_m, y_m, _ = clouds.layer_points_m(directions, BASE_M)
    solid_angles = sky.cube_solid_angles(TEXELS)
    noise = clouds.CloudField.draw(clouds.cloud_rng(seed, 0)).noise(x_m, y_m, clouds.texel_footprint_m(directions, solid_angles, BASE_M))
    weights = solid_angles * (directions[..., 2] > 0)
    threshold = clouds.cover_threshold(noise, weights, oktas)
    return clouds.optical_depth(noise, threshold, float(noise[weights > 0].std())) * (weights > 0), weights


def _cloudy(oktas: int, seed: int = 0, base_m: float = BASE_M, visibility_m: float = VISIBILITY_M,
            texels: int = TEXELS) -> np.ndarray:
    return sky.daylight_sky_texture(SUN, 3.0, texels, clouds=clouds.CloudLayer(oktas, base_m, visibility_m, clouds.cloud_rng(seed, 0)))


def _elevation_deg(texels: int) -> np.ndarray:
    """(6 * texels, texels) elevation [deg] of each texel of a skybox of `texels`-sized faces."""
    return np.degrees(np.arcsin(sky.cube_directions(texels)[..., 2]))


@pytest.mark.parametrize("oktas", [1, 4, 6])
def test_the_clouds_cover_the_sky_dome_in_the_oktas_asked_for(oktas):
    tau, weights = _optical_depth(oktas)
    covered = weights[tau > 0].sum() / weights.sum()
    assert covered == pytest.approx(oktas / 8, abs=0.01)


def test_the_clear_patches_are_the_clear_skys_own_texels():
    # A texel is clear where every point it is the mean of lies between the clouds (or never meets the layer).
    directions, solid_angles = sky.cube_directions(TEXELS), sky.cube_solid_angles(TEXELS)
    weights = solid_angles * (directions[..., 2] > 0)
    samples = clouds.sample_layer(directions, solid_angles, clouds.CloudLayer(4, BASE_M, VISIBILITY_M, None),
                                  clouds.CloudField.draw(clouds.cloud_rng(0, 0)))
    threshold = clouds.cover_threshold(samples.texel_noise, weights.reshape(-1), 4)
    in_cloud = (samples.noise > threshold) & np.isfinite(samples.range_m)
    between = np.bincount(samples.texel, weights=in_cloud, minlength=weights.size).reshape(weights.shape) == 0
    clear = sky.daylight_sky_texture(SUN, 3.0, TEXELS)
    cloudy = _cloudy(4)
    assert np.array_equal(cloudy[between], clear[between])
    assert not np.array_equal(cloudy[~between], clear[~between])


def test_a_cloud_base_is_bright_at_its_thin_edge_and_grey_where_thick():
    tau = np.array([0.0, 2.0, 30.0])
    luminance = clouds.base_luminance_kcd(tau, math.radians(90.0))
    # Nothing scatters where there is no cloud; the two-stream transmittance at tau = 30 with g = 0.85.
    assert luminance[0] == 0.0
    assert luminance[2] == pytest.approx((1 / (1 + 0.75 * 0.15 * 30) - math.exp(-30)) * 100_000 / math.pi / 1000)
    assert luminance[1] > 2 * luminance[2]
    # A lower sun lights the layer less (the sine of its elevation).
    assert clouds.base_luminance_kcd(tau, math.radians(30.0))[2] == pytest.approx(luminance[2] / 2)


def test_clouds_fade_into_the_horizon_haze():
    clear = sky.daylight_sky_texture(SUN, 3.0, TEXELS).astype(float)
    change = np.abs(_cloudy(6).astype(float) - clear).sum(axis=-1)
    elevation = _elevation_deg(TEXELS)
    assert change[(elevation > 0) & (elevation < 3)].mean() < 0.2 * change[elevation > 30].mean()
    assert change[elevation < 0].max() == 0  # the ground hides what is below the horizon


def test_octaves_finer_than_a_texel_fade_out_towards_the_horizon():
    # One texel straight up spans about 1.5 km / 64 texels; near the horizon the layer recedes and stretches.
    directions = np.array([[0.0, 0.0, 1.0], [0.9986, 0.0, 0.0523]])  # up, and 3 deg above the horizon
    footprint = clouds.texel_footprint_m(directions, np.full(2, (math.pi / 2 / TEXELS) ** 2), BASE_M)
    assert footprint[0] == pytest.approx(BASE_M * math.pi / 2 / TEXELS)
    assert footprint[1] > 300 * footprint[0]
    x_m, y_m = np.array([[0.0, 500.0]]), np.array([[0.0, 0.0]])
    # Where points lie kilometres apart only the first octave is left: the same as a field of that octave alone.
    field = clouds.CloudField.draw(clouds.cloud_rng(0, 0))
    coarse = field.noise(x_m, y_m, np.full((1, 2), 1e9))
    sharp = field.noise(x_m, y_m)
    assert not np.array_equal(coarse, sharp)
    first_octave_only = field.noise(x_m, y_m, np.full((1, 2), clouds.CLOUD_WAVELENGTH_M / 2))
    assert np.array_equal(coarse, first_octave_only)


def test_near_the_horizon_a_texel_shows_the_mean_of_the_clouds_along_its_line_of_sight(monkeypatch):
    # 600 m up in 80 km air the clouds keep most of their contrast down to a degree of the horizon, where one
    # texel spans kilometres of the layer. Sampled more finely still, those texels barely move (the mean has
    # converged); drawn from the texel's one direction they move far more. The field is the first octave alone,
    # so that only the sampling differs between the three (finer octaves fade with the points' spacing).
    monkeypatch.setattr(clouds, "CLOUD_OCTAVES", 1)

    def low_clear_sky(spacing_m: float) -> np.ndarray:
        monkeypatch.setattr(clouds, "SUB_SAMPLE_SPACING_M", spacing_m)
        return _cloudy(4, base_m=600.0, visibility_m=80_000.0, texels=128).astype(float)

    finer = low_clear_sky(clouds.CLOUD_WAVELENGTH_M / 16)
    as_built = low_clear_sky(clouds.CLOUD_WAVELENGTH_M / 8)
    one_point = low_clear_sky(1e9)
    elevation = _elevation_deg(128)
    band = (elevation > 1) & (elevation < 6)
    converged = np.abs(as_built - finer).sum(axis=-1)[band].mean()
    aliased = np.abs(one_point - finer).sum(axis=-1)[band].mean()
    assert converged < 0.25 * aliased  # measured: 1.7 against 14.7 levels
    # Higher up one point per texel is enough, and those texels are drawn from it as before, bit for bit.
    high = elevation > 15
    assert np.array_equal(as_built[high], one_point[high])


def test_a_texel_is_sampled_along_its_line_of_sight_only_where_it_spans_much_of_a_cloud():
    footprint_m = np.array([10.0, clouds.SUB_SAMPLE_SPACING_M, 1000.0, 1e6, np.inf])
    assert clouds.sub_sample_counts(footprint_m).tolist() == [1, 1, 5, clouds.MAX_SUB_SAMPLES, clouds.MAX_SUB_SAMPLES]
    directions, solid_angles = sky.cube_directions(TEXELS), sky.cube_solid_angles(TEXELS)
    field = clouds.CloudField.draw(clouds.cloud_rng(0, 0))
    samples = clouds.sample_layer(directions, solid_angles, clouds.CloudLayer(4, BASE_M, VISIBILITY_M, None), field)
    points_per_texel = np.bincount(samples.texel, minlength=directions[..., 0].size).reshape(directions.shape[:-1])
    shares = np.bincount(samples.texel, weights=samples.share, minlength=directions[..., 0].size)
    assert np.allclose(shares, 1.0)  # every texel is the mean of its points
    elevation = _elevation_deg(TEXELS)
    assert points_per_texel[elevation > 30].max() == 1 and points_per_texel[elevation <= 0].max() == 1
    assert points_per_texel[(elevation > 2) & (elevation < 6)].min() > 1
    # Where a texel's top edge is under 1.6 deg, 30 km air leaves a 1500 m cloud under a thousandth of its
    # contrast even there (54 km away: exp(-3.912 * 54 / 30) < 0.001), so one point is enough.
    top_edge_deg = elevation + np.degrees(np.sqrt(solid_angles)) / 2
    assert points_per_texel[(elevation > 0) & (top_edge_deg < 1.6)].max() == 1


def _low_sky_change(cloudy: np.ndarray) -> float:
    """Mean change (sum over RGB, 8-bit levels) from the clear sky of the texels 2-8 deg above the horizon,
    where a sign at 20-100 m stands against the sky for the study's camera."""
    elevation = _elevation_deg(TEXELS)
    clear = sky.daylight_sky_texture(SUN, 3.0, TEXELS).astype(float)
    return float(np.abs(cloudy.astype(float) - clear).sum(axis=-1)[(elevation > 2) & (elevation < 8)].mean())


def test_a_lower_cloud_base_and_clearer_air_show_the_clouds_more_near_the_horizon():
    # Koschmieder's law: the contrast left at slant range r = h / sin(elevation) is exp(-3.912 r / V).
    usual = _low_sky_change(_cloudy(4))
    assert _low_sky_change(_cloudy(4, base_m=600.0)) > 1.5 * usual
    assert _low_sky_change(_cloudy(4, visibility_m=80_000.0)) > 1.5 * usual
    assert _low_sky_change(_cloudy(4, visibility_m=10_000.0)) < 0.5 * usual
    # The cover is the oktas asked for at any height: the threshold is taken over the dome, not the layer.
    directions, solid_angles = sky.cube_directions(TEXELS), sky.cube_solid_angles(TEXELS)
    weights = solid_angles * (directions[..., 2] > 0)
    x_m, y_m, _ = clouds.layer_points_m(directions, 600.0)
    noise = clouds.CloudField.draw(clouds.cloud_rng(0, 0)).noise(x_m, y_m, clouds.texel_footprint_m(directions, solid_angles, 600.0))
    covered = weights[noise > clouds.cover_threshold(noise, weights, 4)].sum() / weights.sum()
    assert covered == pytest.approx(0.5, abs=0.01)


def test_the_cloud_base_and_visibility_are_read_from_the_scenario_and_checked():
    assert (DEFAULTS.cloud_base_m, DEFAULTS.cloud_visibility_km) == (1500.0, 30.0)

    def sky_of(**scenario) -> np.ndarray:
        spec = mujoco.MjSpec()
        sky.add_sky(spec, ScenarioConfig(sky="daylight", cloud_oktas=4, **scenario))
        model = spec.compile()
        return model.tex_data.copy()

    usual = sky_of()
    assert not np.array_equal(sky_of(cloud_base_m=600.0), usual)
    assert not np.array_equal(sky_of(cloud_visibility_km=80.0), usual)
    for key, bad in (("cloud_base_m", 100.0), ("cloud_base_m", math.nan), ("cloud_visibility_km", 0.0)):
        with pytest.raises(ConfigError, match=f"scenario.{key}"):
            ScenarioConfig(sky="daylight", cloud_oktas=4, **{key: bad})


def test_the_field_is_the_seeds_own():
    assert np.array_equal(_cloudy(4, seed=3), _cloudy(4, seed=3))
    assert not np.array_equal(_cloudy(4, seed=3), _cloudy(4, seed=4))


def test_the_scene_draws_clouds_only_when_asked():
    def sky_of(**scenario) -> np.ndarray:
        spec = mujoco.MjSpec()
        sky.add_sky(spec, ScenarioConfig(**scenario))
        model = spec.compile()
        tex = model.texture(sky.SKY_TEXTURE_NAME).id
        return model.tex_data[model.tex_adr[tex]:model.tex_adr[tex] + 3 * model.tex_width[tex] * model.tex_height[tex]]

    assert len(sky_of(sky="daylight")) == 3 * 6 * sky.DAYLIGHT_TEXELS ** 2  # a clear daylight sky as before
    cloudy = sky_of(sky="daylight", cloud_oktas=4)
    assert len(cloudy) == 3 * 6 * clouds.CLOUD_TEXELS ** 2
    assert not np.array_equal(cloudy, sky_of(sky="daylight", cloud_oktas=4, seed=1))
    model, _ = build_scene(with_overrides(SimConfig(), {"scenario": {"town": "town07", "sky": "daylight", "cloud_oktas": 2}}))
    assert model.tex_width[model.texture(sky.SKY_TEXTURE_NAME).id] == clouds.CLOUD_TEXELS


def test_clouds_need_the_daylight_sky_and_leave_the_sun_shining():
    assert ScenarioConfig().cloud_oktas == 0
    with pytest.raises(ConfigError, match='scenario.cloud_oktas = 4 needs scenario.sky = "daylight"'):
        ScenarioConfig(cloud_oktas=4)
    with pytest.raises(ConfigError, match="scenario.cloud_oktas"):
        ScenarioConfig(sky="daylight", cloud_oktas=7)
