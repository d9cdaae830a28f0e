"""The observation's detection rows: class ids, order, clipping, padding and its space."""

import numpy as np

from avsim.config import CameraConfig
from avsim.gym.observation import MAX_DETECTIONS, OTHER_CLASS_ID, detections_array, observation_space
from avsim.perception.base import Detection


def _det(name, conf, box=(10.0, 20.0, 30.0, 60.0)):
    return Detection(name, conf, box, "front")


def test_rows_hold_class_ids_signs_first_most_confident_first_and_zero_padding():
    rows = detections_array([_det("car", 0.99), _det("yield", 0.6), _det("stop_sign", 0.8), _det("speed_limit", 0.7)], 640, 480)
    assert rows.shape == (MAX_DETECTIONS, 6) and rows.dtype == np.float32
    assert rows[:4, 0].tolist() == [1, 3, 2, OTHER_CLASS_ID]  # stop_sign, speed_limit, yield, then the car
    assert rows[:4, 1].tolist() == np.float32([0.8, 0.7, 0.6, 0.99]).tolist()
    assert rows[0, 2:].tolist() == [10.0, 20.0, 30.0, 60.0]
    assert not rows[4:].any()


def test_boxes_are_clipped_to_the_image_and_only_eight_rows_are_kept():
    rows = detections_array([_det("stop_sign", 0.9, (-3.0, -1.0, 650.0, 500.0))], 640, 480)
    assert rows[0, 2:].tolist() == [0.0, 0.0, 640.0, 480.0]
    many = detections_array([_det("stop_sign", c) for c in np.linspace(0.1, 0.9, 12)], 640, 480)
    assert many[:, 1].tolist() == np.float32(np.linspace(0.1, 0.9, 12)[::-1][:MAX_DETECTIONS]).tolist()


def test_every_row_lies_in_the_observation_space():
    space = observation_space(("front",), images=False, detections=True, camera=CameraConfig())
    rows = detections_array([_det("stop_sign", 1.0, (0.0, 0.0, 640.0, 480.0)), _det("bus", 0.2)], 640, 480)
    assert space.contains({"speed_mps": np.zeros(1, np.float32), "detections_front": rows})
    assert set(space.spaces) == {"speed_mps", "detections_front"}
