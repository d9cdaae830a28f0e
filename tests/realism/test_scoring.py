"""What a false stop sign sits on, named by kind, and how much of a labelled sign its box covers."""

import mujoco
import numpy as np

from avsim.realism.scoring import geom_label, geom_under_box, sign_cover


def _two_geom_model() -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(name="tree_right_3/crown", size=[1, 0, 0])
    spec.worldbody.add_geom(name="stop_sign/face", size=[1, 0, 0])
    return spec.compile()


def test_a_box_sits_on_the_geom_most_common_in_its_middle_ninth():
    model = _two_geom_model()
    ids = np.full((96, 128), -1)  # a 2x supersampled segmentation of a 48 x 64 px image
    ids[30:60, 30:60] = 0  # the crown fills the middle ninth of the box below...
    ids[24:66, 24:36] = 1  # ...but for a strip of sign that covers its edges, outside the middle ninth
    assert geom_under_box(model, ids, 48, (12, 12, 33, 33)) == "tree_right/crown"
    assert geom_under_box(model, ids, 48, (0, 0, 6, 6)) == "sky"  # where no geom is
    assert geom_under_box(model, ids, 48, (40, 30, 60, 45)) == "sky"
    assert geom_under_box(model, ids, 48, (200, 200, 220, 220)) == "outside"


def test_geom_labels_drop_copy_numbers_and_fall_back_to_the_body():
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="tree_right_12")
    body.add_geom(name="tree_right_12/crown", size=[1, 0, 0])
    body.add_geom(size=[1, 0, 0])  # unnamed
    spec.worldbody.add_geom(name="bldg_left_-3/roof", size=[1, 0, 0])
    model = spec.compile()
    assert sorted(geom_label(model, g) for g in range(model.ngeom)) == ["bldg_left/roof", "tree_right", "tree_right/crown"]
    assert geom_label(model, -1) == "sky"


def test_sign_cover_is_the_largest_fraction_of_a_labelled_sign_under_the_box():
    signs = np.array([[10.0, 10.0, 20.0, 20.0], [100.0, 100.0, 140.0, 140.0]])
    assert sign_cover((15, 10, 40, 30), signs) == 0.5  # half the first sign, beside it
    assert sign_cover((0, 0, 200, 200), signs) == 1.0
    assert sign_cover((120, 100, 200, 200), signs) == 0.5  # the second, whatever the first
    assert sign_cover((20, 0, 30, 30), signs) == 0.0  # touching an edge covers nothing
    assert sign_cover((0, 0, 5, 5), np.zeros((0, 4))) == 0.0  # no sign in view
