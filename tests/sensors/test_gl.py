"""The offscreen renderer: each one draws into a framebuffer of its own size."""

import mujoco
import numpy as np

from avsim.sensors.gl import OffscreenRenderer

# A red box filling the view of a camera looking down the x axis, before a grey plane.
SCENE = """
<mujoco>
  <visual><global offwidth="1280" offheight="960"/></visual>
  <worldbody>
    <light pos="0 0 10" dir="0 0 -1"/>
    <camera name="cam" pos="0 0 1" xyaxes="0 -1 0 0 0 1" fovy="40"/>
    <geom type="plane" size="50 50 1" rgba="0.5 0.5 0.5 1"/>
    <geom type="box" pos="6 0 1" size="0.1 1 0.6" rgba="0.9 0.1 0.1 1"/>
  </worldbody>
</mujoco>
"""


def test_each_renderer_gets_a_framebuffer_of_its_own_size_and_the_model_keeps_its_settings():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    frames = {}
    for width_px, height_px in ((640, 480), (1600, 1200)):  # smaller and larger than the model's 1280x960
        renderer = OffscreenRenderer(model, width_px, height_px, segmentation=False)
        try:
            assert (renderer._con.offWidth, renderer._con.offHeight) == (width_px, height_px)
            frames[width_px] = renderer.render(data, 0, mujoco.MjvOption()).copy()
        finally:
            renderer.close()
        assert (model.vis.global_.offwidth, model.vis.global_.offheight) == (1280, 960)
    for width_px, frame in frames.items():
        height_px = frame.shape[0]
        centre = frame[height_px // 2, width_px // 2].astype(int)
        # The bottom-right pixel is the plane; in a framebuffer of the model's 1280x960 it would be off the
        # buffer at 1600x1200.
        corner = frame[height_px - 1, width_px - 1].astype(int)
        assert centre[0] - centre[1] > 80, (width_px, centre)  # the red box
        assert corner.min() > 40 and abs(corner[0] - corner[1]) < 10, (width_px, corner)
