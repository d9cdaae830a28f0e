"""Sensor noise: seeded, of the configured level, and part of a run's determinism."""

import numpy as np
import pytest

from avsim.loop import ClosedLoop
from avsim.sensors.noise import SensorNoise
from helpers import make_config

FRAME = np.full((48, 64, 3), 128, np.uint8)


def test_same_seed_same_noise_and_other_seeds_other_noise():
    a, b, c = SensorNoise(2.0, 0), SensorNoise(2.0, 0), SensorNoise(2.0, 1)
    first = a.apply(FRAME)
    assert np.array_equal(first, b.apply(FRAME))
    assert not np.array_equal(first, c.apply(FRAME))
    assert not np.array_equal(first, a.apply(FRAME))  # a fresh pattern every frame


def test_a_noise_that_follows_another_is_left_as_its_own_draw_would_leave_it():
    leader, follower, own = SensorNoise(2.0, 0), SensorNoise(2.0, 0), SensorNoise(2.0, 0)
    assert leader.state_key() == follower.state_key() == own.state_key()
    leader.apply(FRAME)
    own.apply(FRAME)
    assert leader.state_key() != follower.state_key()
    follower.follow(leader)
    assert follower.state_key() == own.state_key() == leader.state_key()
    assert np.array_equal(follower.apply(FRAME), own.apply(FRAME))  # and it draws on as its own draws would
    assert SensorNoise(2.0, 1).state_key() != SensorNoise(2.0, 0).state_key() != SensorNoise(3.0, 0).state_key()


def test_noise_has_the_configured_spread_and_keeps_the_frame_8_bit():
    noisy = SensorNoise(5.0, 0).apply(FRAME)
    assert noisy.dtype == np.uint8 and noisy.shape == FRAME.shape
    assert np.std(noisy.astype(float) - 128) == pytest.approx(5.0, rel=0.05)
    assert abs(np.mean(noisy.astype(float) - 128)) < 0.2


def test_zero_noise_returns_the_frame_untouched():
    assert SensorNoise(0.0, 0).apply(FRAME) is FRAME


def test_clipped_at_the_ends_of_the_range():
    white = np.full((8, 8, 3), 255, np.uint8)
    assert SensorNoise(20.0, 0).apply(white).max() == 255


def _short_detector_run(seed: int, noise_std: float = 3.0) -> list:
    config = make_config(scenario={"speed_kmh": 40.0, "start_speed_kmh": 40.0, "start_dist_m": 45.0, "seed": seed},
                         perception={"kind": "detector", "sensor_noise_std": noise_std})
    loop = ClosedLoop(config)
    try:
        records = [loop.step() for _ in range(12)]
    finally:
        loop.close()
    return [[(d.camera, d.confidence, d.box_xyxy_px) for d in r.detections] for r in records]


def test_detector_runs_with_noise_are_bit_identical_for_a_seed_and_differ_between_seeds():
    first = _short_detector_run(0)
    assert any(first), "the detector saw nothing in 12 steps from 45 m"
    assert _short_detector_run(0) == first
    assert _short_detector_run(1) != first
    assert _short_detector_run(0, noise_std=0.0) != first  # the detector really sees the noise
