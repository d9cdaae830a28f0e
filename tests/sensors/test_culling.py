"""Leaving the geoms a camera cannot see out of a render changes no pixel, and does leave geoms out."""

import mujoco
import numpy as np
import pytest

from avsim.loop import ClosedLoop
from avsim.sensors.culling import FULL_VIEW_NDC, cullable, outside_view, window_of_region
from avsim.sensors.gl import OffscreenRenderer
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from helpers import make_config

WIDTH_PX, HEIGHT_PX = 640, 480


def _place(loop: ClosedLoop, dist_m: float) -> None:
    """The car's bumper `dist_m` before the stop line, on its lane."""
    loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    mujoco.mj_forward(loop.model, loop.data)


@pytest.mark.parametrize("town, materials", [("town03", "flat"), ("town07", "flat"), ("town10", "flat"),
                                             ("town10", "textured")])
def test_culled_renders_are_bit_identical_to_full_ones_in_colour_and_segmentation(town, materials):
    loop = ClosedLoop(make_config(scenario={"town": town, "materials": materials}))
    option = mujoco.MjvOption()
    renderers = {seg: OffscreenRenderer(loop.model, WIDTH_PX, HEIGHT_PX, segmentation=seg) for seg in (False, True)}
    rgba_before = loop.model.geom_rgba.copy()
    try:
        for dist_m in (90.0, 25.0, 6.0):
            _place(loop, dist_m)
            for camera in ("car/front", "car/side"):
                camera_id = loop.model.camera(camera).id
                for seg, renderer in renderers.items():
                    frames = {}
                    for cull in (False, True):
                        renderer.cull = cull
                        frame = renderer.render(loop.data, camera_id, option).astype(np.int32)
                        if seg:  # scene indices differ once geoms are left out; the geom under each pixel must not
                            frame = renderer.geom_id_lookup()[frame[..., 0] | (frame[..., 1] << 8) | (frame[..., 2] << 16)]
                        frames[cull] = (frame, renderer.scene_geom_count)
                    (full, drawn_full), (culled, drawn_culled) = frames[False], frames[True]
                    assert np.array_equal(full, culled), (town, materials, dist_m, camera, seg)
                    assert drawn_culled < drawn_full / 2, (drawn_culled, drawn_full)  # most of a town is out of view
        assert np.array_equal(loop.model.geom_rgba, rgba_before)  # the model is left as it was
    finally:
        for renderer in renderers.values():
            renderer.close()
        loop.close()


SPHERES = """
<mujoco>
  <worldbody>
    <camera name="cam" pos="0 0 0" xyaxes="0 -1 0 0 0 1" fovy="30"/>
    <geom name="ahead" type="sphere" pos="10 0 0" size="1"/>
    <geom name="behind" type="sphere" pos="-10 0 0" size="1"/>
    <geom name="beside" type="sphere" pos="10 8 0" size="1"/>
    <geom name="straddles_edge" type="sphere" pos="10 3.2 0" size="1"/>
    <geom name="floor" type="plane" pos="-50 0 -1" size="0 0 1"/>
  </worldbody>
</mujoco>
"""


def test_only_spheres_wholly_outside_the_frustum_are_out_of_view():
    model = mujoco.MjModel.from_xml_string(SPHERES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    hidden = outside_view(model, data, model.camera("cam").id, aspect=4 / 3)
    # The camera looks along +x; at 10 m its half-width is 10 tan(15 deg) * 4/3 = 3.57 m.
    assert {model.geom(i).name for i in np.flatnonzero(hidden)} == {"behind", "beside"}


def test_a_window_leaves_out_what_lies_outside_that_part_of_the_image():
    model = mujoco.MjModel.from_xml_string(SPHERES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    camera_id = model.camera("cam").id
    # The camera looks along +x with +y on the image's left: "ahead" is at the centre, "straddles_edge"
    # at the left edge. Its left half, grown by a pixel, still holds both; its right half neither.
    left_half = window_of_region((0, 0, 320, 480), 640, 480)
    right_half = window_of_region((320, 0, 640, 480), 640, 480)
    assert left_half == (-1.0, 2 * 321 / 640 - 1, -1.0, 1.0)
    assert outside_view(model, data, camera_id, 4 / 3, FULL_VIEW_NDC).tolist() == \
        outside_view(model, data, camera_id, 4 / 3).tolist()
    hidden = {name: {model.geom(i).name for i in np.flatnonzero(outside_view(model, data, camera_id, 4 / 3, window))}
              for name, window in (("left", left_half), ("right", right_half))}
    assert hidden["left"] == {"behind", "beside"}
    assert hidden["right"] == {"behind", "beside", "straddles_edge"}
    # A band at the top, above the sphere at the centre (1 m in radius at 10 m reaches about 90 px above the
    # centre, row 150).
    top_band = window_of_region((0, 0, 640, 100), 640, 480)
    assert "ahead" in {model.geom(i).name for i in np.flatnonzero(outside_view(model, data, camera_id, 4 / 3, top_band))}


@pytest.mark.parametrize("town", ["town03", "town07", "town10"])
def test_a_region_read_back_alone_has_the_whole_frames_pixels_with_fewer_geoms_drawn(town):
    loop = ClosedLoop(make_config(scenario={"town": town}))
    option = mujoco.MjvOption()
    renderer = OffscreenRenderer(loop.model, WIDTH_PX, HEIGHT_PX, segmentation=False)
    # The perception's two regions of interest, and a patch of road.
    regions = [("car/front", (288, 0, 640, 256)), ("car/side", (0, 0, 640, 256)), ("car/front", (100, 300, 200, 400))]
    fewer = 0
    try:
        for dist_m in (90.0, 25.0, 6.0):
            _place(loop, dist_m)
            for camera, (x0, y0, x1, y1) in regions:
                camera_id = loop.model.camera(camera).id
                whole = renderer.render(loop.data, camera_id, option).copy()
                drawn_whole = renderer.scene_geom_count
                region = renderer.render(loop.data, camera_id, option, (x0, y0, x1, y1))
                assert np.array_equal(region, whole[y0:y1, x0:x1]), (town, dist_m, camera)
                assert renderer.scene_geom_count <= drawn_whole
                fewer += renderer.scene_geom_count < drawn_whole
    finally:
        renderer.close()
        loop.close()
    assert fewer >= 6, fewer  # most views leave some geom out


@pytest.mark.parametrize("change", ["shadow", "reflection", "orthographic"])
def test_culling_is_refused_where_an_unseen_geom_can_change_a_pixel(change):
    xml = SPHERES.replace("<worldbody>", '<worldbody><light pos="0 0 5" castshadow="false"/>')
    xml = {"shadow": xml.replace('castshadow="false"', 'castshadow="true"'),
           "reflection": xml.replace("<worldbody>", '<asset><material name="mirror" reflectance="0.5"/></asset><worldbody>'),
           "orthographic": xml.replace('fovy="30"', 'fovy="30" projection="orthographic"')}[change]
    assert cullable(mujoco.MjModel.from_xml_string(SPHERES.replace("<worldbody>", '<worldbody><light pos="0 0 5" castshadow="false"/>')), 0)
    assert not cullable(mujoco.MjModel.from_xml_string(xml), 0)
