"""The junctions that require no stop of this car, red sign-like boards, and the map's failure modes."""

import math

import numpy as np
import pytest

from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.world.distractors import BOARDS
from avsim.world.hd_map import HdMap
from avsim.world.scene import build_scene
from avsim.world.textures import make_disc_advert, make_hexagon_advert
from avsim.world.towns.base import SIGHT_CORRIDOR_START_X_M
from helpers import make_config


def geom_names(model) -> set[str]:
    return {model.geom(g).name for g in range(model.ngeom)}


def test_the_study_junction_requires_a_stop_and_has_its_stop_line_painted():
    model, info = build_scene(make_config())
    assert info.stop_required and info.stop_sign.kind == "stop_sign"
    assert "road/stop_line" in geom_names(model)


def test_no_stop_sign_puts_a_speed_limit_sign_on_the_post_and_paints_no_stop_line():
    stop_model, stop = build_scene(make_config())
    model, info = build_scene(make_config(scenario={"sign": "none"}))
    assert not info.stop_required
    assert info.stop_sign.kind == "speed_limit" and "stop_sign" not in {s.kind for s in info.signs}
    assert info.stop_sign.base_pos_m == stop.stop_sign.base_pos_m  # the same post: distances compare
    assert "road/stop_line" not in geom_names(model)
    assert "road/crosswalk_0" in geom_names(model)


@pytest.mark.parametrize("yaw_deg", [60.0, 75.0, 90.0, -75.0])
def test_a_stop_sign_turned_to_the_cross_street_is_not_for_this_car(yaw_deg):
    model, info = build_scene(make_config(scenario={"sign_yaw_deg": yaw_deg}))
    assert info.stop_sign.kind == "stop_sign" and not info.stop_required
    assert "road/stop_line" not in geom_names(model)
    # The face turns with its yaw: its normal, world -x when facing the car, now points mostly across the road.
    normal = info.stop_sign.face_points_m(np.array([[0.0, 0.0]]))[0] - np.asarray(info.stop_sign.base_pos_m)
    assert abs(math.degrees(math.atan2(-normal[1], -normal[0]))) == pytest.approx(abs(yaw_deg), abs=1e-6)


@pytest.mark.parametrize("yaw_deg", [0.0, 20.0, -30.0])
def test_a_stop_sign_turned_a_little_is_still_for_this_car(yaw_deg):
    assert build_scene(make_config(scenario={"sign_yaw_deg": yaw_deg}))[1].stop_required


@pytest.mark.parametrize("yaw_deg", [31.0, 45.0, -59.0])
def test_a_sign_turned_halfway_is_refused_as_ambiguous(yaw_deg):
    with pytest.raises(ConfigError, match="sign_yaw_deg"):
        make_config(scenario={"sign_yaw_deg": yaw_deg})


def test_red_sign_like_boards_stand_along_the_approach_as_props_not_signs():
    plain_model, plain = build_scene(make_config(scenario={"sign": "none"}))
    model, info = build_scene(make_config(scenario={"sign": "none", "distractors": "red_signs"}))
    boards = {n for n in geom_names(model) if n.startswith("distractor_") and n.endswith("/face")}
    assert len(boards) == len(BOARDS) >= 3
    assert {s.name for s in info.signs} == {s.name for s in plain.signs}  # no perception's ground truth lists them
    # Outside the stop sign's sight corridor, so they never hide the junction's sign.
    assert all(board.x_m <= SIGHT_CORRIDOR_START_X_M for board in BOARDS)


@pytest.mark.parametrize("make", [make_disc_advert, make_hexagon_advert])
def test_the_boards_are_red_with_white_like_a_stop_sign(make):
    rgb = make().reshape(-1, 3).astype(int)
    face = (rgb != 128).any(axis=1)  # grey outside the outline
    red = (rgb[:, 0] > 150) & (rgb[:, 1] < 60) & (rgb[:, 2] < 80)
    white = (rgb > 230).all(axis=1)
    assert red[face].mean() > 0.6 and 0.05 < white[face].mean() < 0.4


def test_the_map_lists_the_junctions_stop_only_where_the_world_has_one():
    def mapped(**scenario):
        return HdMap.for_scene(0.0, with_overrides(SimConfig(), {"scenario": scenario}).scenario).stop_lines_x_m

    assert mapped() == (0.0,)
    assert mapped(map_stop_line_offset_m=15.0) == (15.0,)
    assert mapped(sign="none") == ()
    assert mapped(sign_yaw_deg=75.0) == ()
    assert mapped(map_error="missing_stop") == ()
    assert mapped(sign="none", map_error="phantom_stop") == (0.0,)


def test_map_errors_that_contradict_the_world_are_refused():
    with pytest.raises(ConfigError, match="missing_stop needs a stop"):
        make_config(scenario={"sign": "none", "map_error": "missing_stop"})
    with pytest.raises(ConfigError, match="phantom_stop needs a junction"):
        make_config(scenario={"map_error": "phantom_stop"})
    with pytest.raises(ConfigError, match="map_error"):
        make_config(scenario={"map_error": "stale"})
