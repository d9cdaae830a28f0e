"""Sun shadows (`scenario.sun_shadow_map_px`): the sun casts them over the road ahead of the car, and they
only take light away; without them the sun is the default renders' light."""

import mujoco
import numpy as np
import pytest

from avsim.sensors.camera import CameraRig
from avsim.vehicle.physics import Vehicle
from avsim.world.scene import EXTENT_M, SUN_SHADOW_AIM_AHEAD_M, SUN_SHADOW_HALF_WIDTH_M, build_scene
from helpers import make_config

# Town10's street with the sun low behind the car on its left: the buildings shade the road.
LOW_SUN = {"town": "town10", "sun_elevation_deg": 32.0, "sun_azimuth_deg": -153.0}


def _placed(size_px: int, car_xs_m: tuple[float, ...] = (-30.0,)):
    """The config, model and data of the scene with the car placed at each of `car_xs_m` in turn."""
    config = make_config(scenario={**LOW_SUN, "sun_shadow_map_px": size_px})
    model, info = build_scene(config)
    data = mujoco.MjData(model)
    vehicle = Vehicle(model, data, config.vehicle)
    for car_x_m in car_xs_m:
        vehicle.place(car_x_m, info.layout.lane_center_y_m, 0.0, 0.0)
        yield config, model, data


def test_the_shadow_map_follows_the_car_and_covers_the_road_ahead():
    for _, model, data in _placed(2048, (-200.0, -30.0)):
        sun = model.light("sun").id
        assert model.light_castshadow[sun] and model.light_mode[sun] == mujoco.mjtCamLight.mjCAMLIGHT_TRACK
        assert model.vis.quality.shadowsize == 2048
        assert model.vis.map.shadowclip * EXTENT_M == pytest.approx(SUN_SHADOW_HALF_WIDTH_M)
        # The shadow map's axis (the light's position along its direction) meets the road ahead of the car.
        position, direction = data.light_xpos[sun], data.light_xdir[sun]
        at_road = position + direction * (position[2] / -direction[2])
        car = data.xpos[model.body("car/car").id]
        assert at_road[:2] == pytest.approx([car[0] + SUN_SHADOW_AIM_AHEAD_M, car[1]], abs=0.5)
    _, model, _ = next(_placed(0))
    sun = model.light("sun").id
    assert not model.light_castshadow[sun] and model.light_bodyid[sun] == 0  # the world's, as before


@pytest.mark.slow  # two Town10 scenes and GL contexts: about 5 s
def test_shadows_only_take_light_away():
    frames = {}
    for size_px in (0, 1024):
        config, model, data = next(_placed(size_px))
        rig = CameraRig(model, config.camera)
        frames[size_px] = rig.render_rgb(data, "front").astype(int)
        ids = rig.render_segmentation(data, "front")
        sky = ids[::ids.shape[0] // 480, ::ids.shape[1] // 640] < 0  # no geom: the sky (one sample per pixel)
        rig.close()
    brighter = (frames[1024] - frames[0]).max(axis=2)
    darker = (frames[0] - frames[1024]).max(axis=2)
    # The two render passes of a shadowed light round differently at a few facade edges: 1-2 % of pixels.
    assert (brighter <= 1).mean() > 0.98
    assert (darker >= 20).mean() > 0.2  # the shaded street
    # Nothing casts a shadow on the sky (but at its edges, where the segmentation sample misses the colour pixel).
    assert sky.mean() > 0.1 and (darker[sky] == 0).mean() > 0.99
