"""`avsim realism --set`: camera and scenario values under every frame; what no frame reads, what a scene draw or a
setting sets, and bad values are refused in one line."""

import pytest

from avsim.cli.overrides import parse_set
from avsim.config import SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.realism.frame_set import FRAME_SET_KEYS, scene_config, scene_draws
from avsim.realism.set_values import REALISM_SET
from avsim.realism.settings import SETTINGS


def test_a_set_value_reaches_every_frame_under_each_setting_and_leaves_the_scene_draw_alone():
    draw = scene_draws(("town10",), 1, seed=0)[0]
    overrides = parse_set(["camera.fovy_deg=40", "scenario.fog_end_m=300"])
    REALISM_SET.check(overrides, (SETTINGS["baseline"], SETTINGS["photo"]))
    for name in ("baseline", "photo"):
        plain, given = scene_config(draw, SETTINGS[name]), scene_config(draw, SETTINGS[name], overrides)
        assert (given.camera.fovy_deg, given.scenario.fog_end_m) == (40.0, 300.0)
        assert given == with_overrides(plain, overrides)  # nothing else moves: the setting's values and the draw's
    assert scene_config(draw, SETTINGS["photo"], {}) == scene_config(draw, SETTINGS["photo"])


def test_the_frame_set_keys_are_what_a_scene_draw_sets():
    draw = scene_draws(("town03",), 1, seed=0)[0]
    config, default = scene_config(draw, SETTINGS["baseline"]), SimConfig()
    assert {f"scenario.{key}" for key in ("town", "seed", "sun_intensity")} <= set(FRAME_SET_KEYS)
    assert config.scenario.town == "town03" and config.scenario.seed == draw.seed != default.scenario.seed


@pytest.mark.parametrize("item, named", [
    ("perception.sensor_noise_std=3", "reads camera and scenario keys only"),
    ("policy.conf_threshold=0.6", "reads camera and scenario keys only"),
    ("scenario.town=town07", "sets it itself; every scene draw sets it"),
    ("scenario.sun_intensity=0.5", "sets it itself; every scene draw sets it"),
    ("camera.supersample=3", "--settings photo sets it too"),
    ("camera=3", "a key names its section and the key"),
    ("camera.fovy_deg=-5", "--set under --settings baseline"),
    ("camera.no_such_key=1", "--set under --settings baseline"),
])
def test_what_no_frame_reads_what_the_draws_or_a_setting_set_and_bad_values_are_refused(item, named):
    with pytest.raises(ConfigError, match=named) as caught:
        REALISM_SET.check(parse_set([item]), (SETTINGS["baseline"], SETTINGS["photo"]))
    assert "\n" not in str(caught.value)
