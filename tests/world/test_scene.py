"""Scene composition: towns, the stop sign's geometry and placement, the car, textures."""

import numpy as np
import pytest

from avsim.errors import ConfigError, TextureError
from avsim.loop import ClosedLoop
from avsim.world.road import APPROACH_LENGTH_M
from avsim.world.scene import build_scene
from avsim.world.textures import save_texture_png
from avsim.world.towns import PLACEMENTS, TOWNS
from helpers import make_config


@pytest.fixture(scope="module")
def scenes():
    return {town: build_scene(make_config(scenario={"town": town})) for town in TOWNS.names()}


def test_every_town_has_an_approach_road_of_at_least_250_m(scenes):
    for model, info in scenes.values():
        road = model.geom("road/asphalt")
        assert road.pos[0] - road.size[0] <= info.stop_line_x_m - 250.0
    assert APPROACH_LENGTH_M >= 250.0


def test_towns_are_distinct_scenes(scenes):
    names = {town: {model.geom(g).name for g in range(model.ngeom)} for town, (model, _) in scenes.items()}
    assert any(n.startswith("barn") for n in names["town07"])
    assert any(n.startswith("parked") for n in names["town03"]) and any(n.startswith("bldg") for n in names["town03"])
    assert any(n.startswith("tower") for n in names["town10"]) and any(n.startswith("sign_yield") for n in names["town10"])
    lanes = {town: TOWNS.get(town).layout.lanes_per_direction for town in TOWNS.names()}
    assert lanes == {"town07": 1, "town03": 2, "town10": 3}


def test_stop_sign_is_a_762_mm_octagon_with_its_bottom_at_2_1_m(scenes):
    _, info = scenes["town07"]
    corners = info.stop_sign.corners_m()
    assert len(corners) == 8
    assert np.ptp(corners[:, 2]) == pytest.approx(0.762)  # flat to flat
    assert np.ptp(corners[:, 1]) == pytest.approx(0.762)
    assert corners[:, 2].min() == pytest.approx(2.1, abs=0.05)


@pytest.mark.parametrize("placement,offset_m", [("near", 0.5), ("standard", 2.0), ("far", 5.5)])
def test_placement_is_measured_from_the_travelled_lane_edge(placement, offset_m):
    _, info = build_scene(make_config(scenario={"placement": placement}))
    assert info.layout.lane_edge_y_m - info.stop_sign.base_pos_m[1] == pytest.approx(offset_m)
    assert PLACEMENTS.get(placement) == offset_m


def test_car_is_sedan_sized():
    loop = ClosedLoop(make_config())
    assert loop.vehicle.mass_kg == pytest.approx(1500, rel=0.03)
    front = loop.model.body("car/hub_fl").pos[0]
    rear = loop.model.body("car/hub_rl").pos[0]
    assert front - rear == pytest.approx(2.7)
    loop.close()


def test_sign_texture_swaps_from_any_png_at_run_time(tmp_path):
    blue = np.zeros((256, 256, 3), np.uint8)
    blue[..., 2] = 230
    path = tmp_path / "blue.png"
    save_texture_png(path, blue)
    loop = ClosedLoop(make_config(scenario={"sign": str(path), "placement": "near"}))
    face_x = loop.scene.stop_sign.face_center_m[0]
    loop.vehicle.place(face_x - 20.0 - 0.55, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    sign = loop.scene.stop_sign
    x0, y0, x1, y1 = (int(round(v)) for v in loop.rig.sign_boxes(loop.data, "front", {sign.name: (loop.model.geom(sign.face_geom).id, sign.corners_m())})[sign.name])
    patch = loop.rig.render_rgb(loop.data, "front")[y0 + 2:y1 - 2, x0 + 2:x1 - 2].reshape(-1, 3).astype(int)
    loop.close()
    assert (patch[:, 2] > patch[:, 0] + 60).mean() > 0.8


def test_unknown_sign_name_is_a_config_error():
    with pytest.raises(ConfigError, match="unknown sign texture"):
        build_scene(make_config(scenario={"sign": "no_such_texture"}))


def test_missing_texture_file_is_a_texture_error(tmp_path):
    with pytest.raises(TextureError):
        build_scene(make_config(scenario={"sign": str(tmp_path / "missing.png")}))


def test_non_square_stop_texture_is_refused(tmp_path):
    path = tmp_path / "wide.png"
    save_texture_png(path, np.zeros((100, 200, 3), np.uint8))
    with pytest.raises(TextureError, match="width:height"):
        build_scene(make_config(scenario={"sign": str(path)}))


@pytest.mark.parametrize("town", ["town99", "Town07"])
def test_unknown_town_is_a_config_error(town):
    with pytest.raises(ConfigError, match="unknown town"):
        build_scene(make_config(scenario={"town": town}))


def test_same_layout_seed_gives_the_same_scene_and_another_seed_a_different_one():
    a, _ = build_scene(make_config(scenario={"town": "town03", "layout_seed": 0}))
    b, _ = build_scene(make_config(scenario={"town": "town03", "layout_seed": 0}))
    c, _ = build_scene(make_config(scenario={"town": "town03", "layout_seed": 1}))
    assert np.array_equal(a.geom_size, b.geom_size)
    assert a.ngeom != c.ngeom or not np.array_equal(a.geom_size, c.geom_size)
