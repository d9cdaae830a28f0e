"""What a false stop sign sits on, named by kind."""

import mujoco

from avsim.realism.scoring import geom_label


def test_geom_labels_drop_copy_numbers_and_fall_back_to_the_body():
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="tree_right_12")
    body.add_geom(name="tree_right_12/crown", size=[1, 0, 0])
    body.add_geom(size=[1, 0, 0])  # unnamed
    spec.worldbody.add_geom(name="bldg_left_-3/roof", size=[1, 0, 0])
    model = spec.compile()
    assert sorted(geom_label(model, g) for g in range(model.ngeom)) == ["bldg_left/roof", "tree_right", "tree_right/crown"]
    assert geom_label(model, -1) == "sky"
