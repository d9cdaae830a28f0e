"""Input purification: JPEG re-compression and the median filter, as the perception applies them."""

import numpy as np
import pytest
import torch

from avsim.config import PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.base import Detection
from avsim.perception.factory import build_frame_detector
from avsim.perception.purify import PurifiedDetector, build_purifier, jpeg_recompress, median_blur, purify_tensor


def frame(seed: int = 0, h: int = 48, w: int = 64) -> np.ndarray:
    """A smooth picture plus sparse impulse noise (the kind of fine detail purification removes)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    base = np.stack([x * 3, y * 4, (x + y) * 2], axis=-1).astype(np.float64)
    noisy = base.copy()
    mask = rng.random((h, w)) < 0.05
    noisy[mask] = 255 - noisy[mask]
    return np.clip(noisy, 0, 255).astype(np.uint8), np.clip(base, 0, 255).astype(np.uint8)


def test_jpeg_and_median_keep_the_frame_shape_and_are_deterministic():
    image, _ = frame()
    for purify in (lambda im: jpeg_recompress(im, 75), lambda im: median_blur(im, 3)):
        out = purify(image)
        assert out.shape == image.shape and out.dtype == np.uint8
        assert np.array_equal(out, purify(image.copy()))


def test_the_median_filter_removes_impulse_noise():
    noisy, clean = frame()
    inner = (slice(2, -2), slice(2, -2))  # away from the replicated border
    before = np.abs(noisy.astype(int) - clean)[inner].mean()
    after = np.abs(median_blur(noisy, 3).astype(int) - clean)[inner].mean()
    assert after < before / 3


def test_lower_jpeg_quality_changes_the_frame_more():
    noisy, _ = frame()
    err = {q: np.abs(jpeg_recompress(noisy, q).astype(int) - noisy).mean() for q in (95, 75, 30)}
    assert 0 < err[95] < err[75] < err[30]


def test_the_configured_purifier_follows_the_config_keys():
    image, _ = frame()
    assert build_purifier(PerceptionConfig()) is None
    assert np.array_equal(build_purifier(PerceptionConfig(purify="jpeg", purify_jpeg_quality=40))(image), jpeg_recompress(image, 40))
    assert np.array_equal(build_purifier(PerceptionConfig(purify="median", purify_median_kernel_px=5))(image), median_blur(image, 5))


def test_purify_tensor_equals_the_deployed_purifier_on_8_bit_frames():
    image, _ = frame()
    purifier = build_purifier(PerceptionConfig(purify="jpeg"))
    tensor = torch.from_numpy(image).permute(2, 0, 1)[None].float() / 255
    out = purify_tensor(tensor, purifier)
    assert out.shape == tensor.shape and out.dtype == tensor.dtype
    assert torch.equal((out[0].permute(1, 2, 0) * 255).round().to(torch.uint8), torch.from_numpy(purifier(image)))


class Recorder:
    """A frame detector that remembers the image it was given."""

    def detect(self, image_rgb, camera, *, region_px=None):
        self.seen, self.region = image_rgb, region_px
        return [Detection("stop_sign", 0.9, (1.0, 2.0, 3.0, 4.0), camera)]


def test_the_detector_sees_the_purified_frame_in_its_region():
    image, _ = frame()
    inner = Recorder()
    detections = PurifiedDetector(inner, lambda im: median_blur(im, 3)).detect(image, "front", region_px=(0, 0, 32, 32))
    assert np.array_equal(inner.seen, median_blur(image, 3)) and inner.region == (0, 0, 32, 32)
    assert detections[0].class_name == "stop_sign"


def test_every_pixel_perception_can_be_purified_but_not_the_oracle():
    assert isinstance(build_frame_detector(PerceptionConfig(purify="median")), PurifiedDetector)
    with pytest.raises(ConfigError, match="purify works on pixels"):
        PerceptionConfig(kind="oracle", purify="jpeg")
    with pytest.raises(ConfigError, match="purify_median_kernel_px"):
        PerceptionConfig(purify="median", purify_median_kernel_px=4)
    with pytest.raises(ConfigError, match="perception.purify must be"):
        PerceptionConfig(purify="blur")
