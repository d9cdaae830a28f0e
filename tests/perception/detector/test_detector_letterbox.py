"""Letterbox geometry: exact box round trips and the identity at the deployed size."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from avsim.perception.detector.letterbox import PAD_VALUE, Letterbox, fit, letterbox
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE

BOXES = np.array([[0.0, 0.0, 10.5, 7.25], [100.3, 20.7, 180.9, 99.1], [611.2, 300.0, 640.0, 360.0]])


@pytest.mark.parametrize("image_size", [(640, 480), (1280, 720), (500, 700), (333, 251)])
@pytest.mark.parametrize("input_size", [DEPLOY_INPUT_SIZE, (512, 384), (320, 320)])
def test_box_round_trip(image_size, input_size):
    box = fit(*image_size, input_size)
    there = box.to_input(BOXES)
    np.testing.assert_allclose(box.to_image(there), BOXES, atol=1e-4)
    w, h = image_size
    corners = box.to_input(np.array([[0.0, 0.0, w, h]]))[0]
    assert corners[0] >= 0 and corners[1] >= 0 and corners[2] <= input_size[0] + 1e-6 and corners[3] <= input_size[1] + 1e-6
    assert np.isclose(corners[2] - corners[0], input_size[0], atol=1) or np.isclose(corners[3] - corners[1], input_size[1], atol=1)


def test_deployed_size_is_identity_for_camera_frames():
    image = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    tensor, box = letterbox(image, DEPLOY_INPUT_SIZE)
    assert box == Letterbox(1.0, 0.0, 0.0, 640, 480)
    assert tensor.shape == (3, 480, 640) and tensor.dtype == torch.float32
    np.testing.assert_allclose(tensor.permute(1, 2, 0).numpy() * 255.0, image, atol=1e-3)


def test_pads_grey_and_places_pixels_where_the_map_says():
    image = np.zeros((100, 200, 3), np.uint8)
    image[40:60, 100:120] = 255  # a white square, continuous box [100, 40, 120, 60]
    tensor, box = letterbox(image, (128, 128))
    assert box.scale == pytest.approx(0.64) and box.pad_x == 0 and box.pad_y == 32
    arr = tensor.permute(1, 2, 0).numpy()
    assert tensor.min() >= 0 and tensor.max() <= 1
    np.testing.assert_allclose(arr[:10, :, 0], PAD_VALUE / 255.0, atol=1e-6)
    np.testing.assert_allclose(arr[-10:, :, 0], PAD_VALUE / 255.0, atol=1e-6)
    x0, y0, x1, y1 = box.to_input(np.array([[100, 40, 120, 60]]))[0]
    cols = np.where(arr[:, :, 0].max(axis=0) > 0.5)[0]
    rows = np.where(arr[:, :, 0].max(axis=1) > 0.5 + 0.1)[0]
    assert abs(cols[0] - x0) <= 1 and abs(cols[-1] + 1 - x1) <= 1
    assert abs(rows[0] - y0) <= 1 and abs(rows[-1] + 1 - y1) <= 1


def test_rejects_non_uint8_images():
    with pytest.raises(ValueError, match="uint8"):
        letterbox(np.zeros((480, 640, 3), np.float32))
