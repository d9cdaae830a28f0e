"""The render settings as config: the keys each sets, and the config it gives under a command's --set values."""

import dataclasses

import pytest

from avsim.config import SimConfig
from avsim.realism.settings import BASELINE, SETTINGS


def _changed_keys(config: SimConfig) -> set[str]:
    """The dotted keys where `config` differs from the defaults."""
    default = SimConfig()
    return {f"{section.name}.{field.name}"
            for section in dataclasses.fields(SimConfig)
            for field in dataclasses.fields(getattr(default, section.name))
            if getattr(getattr(config, section.name), field.name) != getattr(getattr(default, section.name), field.name)}


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_a_setting_sets_its_keys_and_nothing_else(name):
    setting = SETTINGS[name]
    changed = _changed_keys(setting.config())
    assert set(setting.keys) <= changed, name
    # A camera preset brings its own size and fields of view (docs/realism_camera.md).
    derived = {key for key in changed - setting.keys if key.startswith("camera.")} if "camera.preset" in setting.keys else set()
    assert changed == setting.keys | derived, name


def test_the_baseline_sets_nothing_and_set_values_go_over_a_setting():
    assert SETTINGS[BASELINE].keys == frozenset() and SETTINGS[BASELINE].config() == SimConfig()
    config = SETTINGS["photo"].config({"camera": {"jpeg_quality": 50}, "scenario": {"fog_end_m": 400.0}})
    assert config.camera.jpeg_quality == 50 and config.scenario.fog_end_m == 400.0
    assert config.camera.supersample == SETTINGS["photo"].config().camera.supersample == 2


def test_the_windows_with_multisampling_are_the_windows_under_a_set_of_four_samples():
    # docs/realism_filtering.md measured this render as `--setting textured_window_geometry --set camera.offsamples=4`.
    assert SETTINGS["textured_window_geometry_msaa4"].config() == SETTINGS["textured_window_geometry"].config({"camera": {"offsamples": 4}})
