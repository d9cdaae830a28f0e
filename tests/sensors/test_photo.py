"""The photographic model: off by default, exact on regions, and each stage doing what its optics say."""

import math

import numpy as np
import pytest

from avsim.config import CameraConfig
from avsim.errors import ConfigError
from avsim.loop import ClosedLoop
from avsim.sensors.noise import SensorNoise
from avsim.sensors.photo import PhotoModel
from helpers import make_config

PHOTO = {"supersample": 2, "lens_mtf50_cyc_per_px": 0.3, "jpeg_quality": 85}


@pytest.fixture(scope="module")
def photo_loop():
    """Town07 with every photographic stage on, 30 m before the sign."""
    loop = ClosedLoop(make_config(camera=PHOTO, scenario={"start_dist_m": 30.0}))
    yield loop
    loop.close()


def test_the_default_camera_has_no_photographic_stage():
    model = PhotoModel.from_config(CameraConfig())
    assert (model.supersample, model.lens_sigma_px, model.jpeg_quality) == (1, 0.0, 0)
    frame = np.arange(48 * 3, dtype=np.uint8).reshape(4, 12, 3)
    assert model.integrate(frame) is frame and model.lens(frame) is frame and model.encode(frame) is frame
    assert model.padded_region((5, 6, 7, 8), 640, 480) == (5, 6, 7, 8)


def test_the_lens_blur_has_the_mtf50_it_is_given():
    """A Gaussian PSF's MTF at the stated MTF50 is one half: measured on a blurred sine grating."""
    mtf50 = 0.2
    model = PhotoModel.from_config(CameraConfig(lens_mtf50_cyc_per_px=mtf50))
    x = np.arange(400)
    grating = (127.5 + 100 * np.sin(2 * math.pi * mtf50 * x)).astype(np.float32)
    image = np.repeat(np.repeat(grating[None, :, None], 8, axis=0), 3, axis=2)
    blurred = model.lens(image)[4, 50:350, 0]  # 60 whole periods, away from the borders
    amplitude = 2 * abs(np.mean((blurred - blurred.mean()) * np.exp(-2j * math.pi * mtf50 * x[50:350])))
    assert amplitude / 100 == pytest.approx(0.5, abs=0.02)


def test_photosite_integration_is_the_box_mean_of_its_samples():
    model = PhotoModel(supersample=2)
    rendered = np.random.default_rng(0).integers(0, 256, (8, 6, 3), dtype=np.uint8)
    means = rendered.reshape(4, 2, 3, 2, 3).astype(float).mean(axis=(1, 3))
    assert np.abs(model.integrate(rendered).astype(float) - means).max() <= 0.5


def test_a_region_through_every_stage_is_the_whole_frame_cropped(photo_loop):
    """Lens, photosites, noise and JPEG: a region gets the very pixels of the whole frame, zero elsewhere."""
    region = (203, 117, 421, 290)
    whole = photo_loop.rig.render_rgb(photo_loop.data, "front", noise=SensorNoise(2.0, seed=3))
    part = photo_loop.rig.render_rgb(photo_loop.data, "front", region, noise=SensorNoise(2.0, seed=3))
    x0, y0, x1, y1 = region
    assert np.array_equal(part[y0:y1, x0:x1], whole[y0:y1, x0:x1])
    part[y0:y1, x0:x1] = 0
    assert not part.any()


def test_the_photographic_frame_is_the_same_scene_with_edges_mixed(photo_loop):
    """Same scene and pose without the stages: close on average, but its edges now hold mixtures of
    the colours either side (a flat-shaded render at one sample a pixel has few distinct colours)."""
    plain = ClosedLoop(make_config(scenario={"start_dist_m": 30.0}))
    try:
        sharp = plain.rig.render_rgb(plain.data, "front")
    finally:
        plain.close()
    soft = photo_loop.rig.render_rgb(photo_loop.data, "front")
    assert np.abs(soft.astype(float) - sharp).mean() < 4.0

    def colours(image: np.ndarray) -> int:
        return len(np.unique(image.reshape(-1, 3), axis=0))

    assert colours(soft) > 2 * colours(sharp)


@pytest.mark.parametrize("key, value", [("supersample", 5), ("lens_mtf50_cyc_per_px", 0.01), ("jpeg_quality", 101)])
def test_out_of_range_photographic_keys_are_refused_by_name(key, value):
    with pytest.raises(ConfigError, match=f"camera.{key}"):
        CameraConfig(**{key: value})
