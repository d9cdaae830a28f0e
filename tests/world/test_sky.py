"""The sky: the skybox's texel directions are MuJoCo's, the daylight sky follows its sun, and the
default gradient is unchanged."""

import math

import mujoco
import numpy as np
import pytest

from avsim.config import ScenarioConfig, SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.world import sky
from avsim.world.scene import build_scene


def _texture(model: mujoco.MjModel, name: str = sky.SKY_TEXTURE_NAME) -> np.ndarray:
    tex = model.texture(name).id
    width, height = model.tex_width[tex], model.tex_height[tex]
    start = model.tex_adr[tex]
    return model.tex_data[start:start + width * height * 3].reshape(height, width, 3)


def test_cube_directions_are_where_mujoco_draws_each_texel():
    # A skybox whose every texel encodes its own direction, rendered by cameras looking six ways: each
    # pixel's colour must be the direction of its ray.
    texels = 64
    encode = lambda d: np.clip(np.rint((d + 1) / 2 * 255), 0, 255).astype(np.uint8)
    spec = mujoco.MjSpec()
    texture = spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX)
    texture.width, texture.height, texture.nchannel = texels, 6 * texels, 3
    texture.data = encode(sky.cube_directions(texels)).tobytes()
    looks = [(1, 0, 0.3), (0, 1, 0.2), (-1, 0.3, 0.1), (0.2, -1, -0.2), (0.1, 0.2, 1), (0.2, 0.1, -1)]
    for k, forward in enumerate(looks):
        forward = np.asarray(forward, float) / np.linalg.norm(forward)
        up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        right = np.cross(forward, up) / np.linalg.norm(np.cross(forward, up))
        spec.worldbody.add_camera(name=f"c{k}", xyaxes=[*right, *np.cross(right, forward)], fovy=60)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    size = 48
    focal_px = size / 2 / math.tan(math.radians(30))
    u, v = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    rays_camera = np.stack([(u - size / 2) / focal_px, -(v - size / 2) / focal_px, -np.ones_like(u)], axis=-1)
    with mujoco.Renderer(model, size, size) as renderer:
        for k in range(len(looks)):
            renderer.update_scene(data, camera=f"c{k}")
            image = renderer.render().astype(int)
            rays = rays_camera @ data.cam_xmat[k].reshape(3, 3).T
            expected = encode(rays / np.linalg.norm(rays, axis=-1, keepdims=True)).astype(int)
            assert np.abs(image - expected).max() <= 2, looks[k]


def test_cube_solid_angles_cover_the_sphere():
    assert sky.cube_solid_angles(32).sum() == pytest.approx(4 * math.pi, rel=1e-3)


def test_the_gradient_skys_mean_luminance_is_the_builtin_textures():
    spec = mujoco.MjSpec()
    sky.add_sky(spec, ScenarioConfig())
    rgb = _texture(spec.compile()) / 255
    measured = sky.upper_hemisphere_mean_luminance(sky.srgb_decode(rgb), sky.GRADIENT_TEXELS)
    assert measured == pytest.approx(sky.GRADIENT_MEAN_LINEAR_LUMINANCE, abs=1e-3)


def test_srgb_encode_and_decode_are_inverse():
    values = np.linspace(0, 1, 101)
    assert np.allclose(sky.srgb_decode(sky.srgb_encode(values)), values, atol=1e-9)


def test_the_daylight_locus_passes_through_d65():
    assert sky.on_daylight_locus(np.float64(0.3127)) == pytest.approx(0.3290, abs=5e-4)


@pytest.mark.parametrize("elevation_deg, azimuth_deg", [(30.0, 20.0), (60.0, -150.0)])
def test_the_daylight_sky_is_brightest_about_its_sun_and_bluest_away_from_it(elevation_deg, azimuth_deg):
    texels = 32
    sun = sky.sun_direction(elevation_deg, azimuth_deg)
    directions = sky.cube_directions(texels)
    x, _, luminance = sky.preetham_xyY(directions, sun, 3.0)
    above = directions[..., 2] > 0.05
    angle_deg = np.degrees(np.arccos(np.clip(directions @ sun, -1, 1)))
    assert angle_deg[above][np.argmax(luminance[above])] < 15  # the aureole
    assert 50 < angle_deg[above][np.argmin(luminance[above])] < 130  # the dark band about 90 degrees off
    # Bluer (lower x) high in the sky away from the sun than at the horizon.
    far_high = above & (angle_deg > 70) & (directions[..., 2] > 0.7)
    far_horizon = (np.abs(directions[..., 2]) < 0.05) & (angle_deg > 70)
    assert x[far_high].mean() < x[far_horizon].mean() - 0.02
    texture = sky.daylight_sky_texture(sun, 3.0, texels).astype(float)
    assert (texture[far_high][:, 2] > texture[far_high][:, 0] + 30).all()  # blue sky, not grey


def test_the_daylight_sky_keeps_the_gradients_brightness_until_it_clips():
    texels = 32
    texture = sky.daylight_sky_texture(sky.sun_direction(45.0, 0.0), 3.0, texels)
    mean = sky.upper_hemisphere_mean_luminance(sky.srgb_decode(texture / 255), texels)
    # Clipping about the sun only takes light away.
    assert 0.8 * sky.GRADIENT_MEAN_LINEAR_LUMINANCE < mean <= sky.GRADIENT_MEAN_LINEAR_LUMINANCE + 0.01


def test_the_scene_draws_the_daylight_sky_of_its_own_sun_and_the_gradient_by_default():
    def sky_of(**scenario) -> np.ndarray:
        model, _ = build_scene(with_overrides(SimConfig(), {"scenario": {"town": "town07", **scenario}}))
        return _texture(model)

    gradient = sky_of()
    assert gradient.shape == (6 * sky.GRADIENT_TEXELS, sky.GRADIENT_TEXELS, 3)
    east, west = sky_of(sky="daylight", sun_azimuth_deg=0.0), sky_of(sky="daylight", sun_azimuth_deg=180.0)
    assert east.shape == (6 * sky.DAYLIGHT_TEXELS, sky.DAYLIGHT_TEXELS, 3)
    directions = sky.cube_directions(sky.DAYLIGHT_TEXELS)
    toward_east = (directions[..., 0] > 0.9) & (directions[..., 2] > 0)
    assert east[toward_east].mean() > west[toward_east].mean() + 10
    assert not np.array_equal(sky_of(sky="daylight", sky_turbidity=6.0), sky_of(sky="daylight"))
    darker = sky_of(sky="daylight", sun_azimuth_deg=0.0, sky_exposure_ev=-1.0).astype(float)
    # One stop down halves the linear light of every texel that did not clip (to rounding).
    unclipped = east.max(axis=-1) < 250
    halved = sky.srgb_decode(darker[unclipped] / 255) / sky.srgb_decode(east[unclipped] / 255)
    assert np.median(halved) == pytest.approx(0.5, abs=0.02)


def test_exposure_moves_the_gradient_skys_colours_by_stops_and_leaves_the_default_alone():
    assert sky.exposed_rgb(sky.GRADIENT_ZENITH_RGB, 0.0) == list(sky.GRADIENT_ZENITH_RGB)
    darker = sky.srgb_decode(np.asarray(sky.exposed_rgb(sky.GRADIENT_ZENITH_RGB, -1.0)))
    assert darker == pytest.approx(sky.srgb_decode(np.asarray(sky.GRADIENT_ZENITH_RGB)) / 2)
    assert sky.exposed_rgb(sky.GRADIENT_NADIR_RGB, 1.0) == pytest.approx([1.0, 1.0, 1.0])  # twice its light clips to white

    def gradient_texture(exposure_ev: float) -> np.ndarray:
        spec = mujoco.MjSpec()
        sky.add_sky(spec, ScenarioConfig(sky_exposure_ev=exposure_ev))
        return _texture(spec.compile()).astype(float)

    zenith_row = sky.GRADIENT_TEXELS * 2 + sky.GRADIENT_TEXELS // 2  # the middle of the "up" face
    assert gradient_texture(-1.0)[zenith_row].mean() < gradient_texture(0.0)[zenith_row].mean() - 30


def test_sky_is_a_named_choice_and_turbidity_is_ranged():
    assert ScenarioConfig().sky == "gradient"
    with pytest.raises(ConfigError, match="scenario.sky"):
        ScenarioConfig(sky="sunset")
    with pytest.raises(ConfigError, match="scenario.sky_turbidity"):
        ScenarioConfig(sky_turbidity=1.0)
