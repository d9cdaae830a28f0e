"""The benchmark's frame set: the experiment files' daylight, fixed by its seed, the same for every setting."""

import tomllib
from pathlib import Path

from avsim.realism.frame_set import (BIN_EDGES_M, EXPERIMENT_LIGHTING, FRAME_SET_KEYS, PLACEMENT_ORDER,
                                     SENSOR_NOISE_STD_LEVELS, _scene_keys, bin_edges_m, scene_config, scene_draws)
from avsim.realism.settings import SETTINGS
from avsim.world.towns import PLACEMENTS

EXPERIMENT = Path(__file__).resolve().parents[2] / "experiments" / "coco_detector.toml"


def test_the_lighting_and_noise_are_the_coco_experiment_files():
    spec = tomllib.loads(EXPERIMENT.read_text())
    assert {key: tuple(map(float, span)) for key, span in spec["vary"]["scenario"].items()} == EXPERIMENT_LIGHTING
    assert spec["defaults"]["perception"]["sensor_noise_std"] == SENSOR_NOISE_STD_LEVELS


def test_scene_draws_are_fixed_by_the_seed_and_cycle_the_placements():
    draws = scene_draws(("town07", "town10"), 4, seed=0)
    assert draws == scene_draws(("town07", "town10"), 4, seed=0)
    assert draws != scene_draws(("town07", "town10"), 4, seed=1)
    assert [d.placement for d in draws[:4]] == [*PLACEMENT_ORDER, PLACEMENT_ORDER[0]]
    assert set(PLACEMENT_ORDER) == set(PLACEMENTS.names())
    for draw in draws:
        for key, (lo, hi) in EXPERIMENT_LIGHTING.items():
            assert lo <= getattr(draw, key) <= hi
    # A town's draws do not depend on which other towns are in the set.
    assert scene_draws(("town10",), 4, seed=0) == draws[4:]


def test_a_setting_changes_the_camera_and_nothing_of_the_scene():
    draw = scene_draws(("town03",), 1, seed=0)[0]
    baseline, photo = scene_config(draw, SETTINGS["baseline"]), scene_config(draw, SETTINGS["photo"])
    assert baseline.scenario == photo.scenario and baseline.camera != photo.camera
    assert (photo.camera.supersample, photo.camera.jpeg_quality) == (2, 90)
    assert baseline.scenario.town == "town03" and baseline.scenario.sign == "clean"


def test_the_keys_a_realism_set_may_not_give_are_those_a_scene_draw_sets():
    draw = scene_draws(("town10",), 1, seed=0)[0]
    assert sorted(f"scenario.{key}" for key in _scene_keys(draw)) == sorted(FRAME_SET_KEYS)


def test_each_scene_draw_has_clouds_of_its_own():
    first, second = (scene_config(draw, SETTINGS["scattered_clouds"]) for draw in scene_draws(("town07",), 2, seed=0))
    assert first.scenario.cloud_oktas == 4 and first.scenario.seed != second.scenario.seed


def test_the_bins_run_from_10_m_to_the_farthest_asked_for():
    assert BIN_EDGES_M == bin_edges_m() == (10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60)
    assert bin_edges_m(100)[:len(BIN_EDGES_M)] == BIN_EDGES_M and bin_edges_m(100)[-1] == 100
