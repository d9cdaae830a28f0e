"""`avsim realism --set KEY=VALUE`: one config value under every frame of the benchmark.

The benchmark draws its frames from `camera` and `scenario` keys alone (`avsim.realism.frame_set.scene_config`) and
scores them with networks of its own choosing (`--networks`), so a `--set` may give a `camera` or `scenario` key: a
sensor's noise, a field of view, a material, fog. What is refused, in one line before anything renders:
- a key of another section (a policy, a perception, the vehicle): no frame or score would read it;
- a key every scene draw sets itself (town, placement, sign, seed, the sun: `FRAME_SET_KEYS`), which `--towns` and
  `--seed` choose;
- a key one of the `--settings` sets: the --set would quietly undo part of that setting;
- an unknown key or a bad value, checked under every setting.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from avsim.config import SimConfig, with_overrides
from avsim.config_owners import dotted_keys
from avsim.errors import ConfigError
from avsim.realism.frame_set import FRAME_SET_KEYS
from avsim.realism.settings import RenderSetting

RENDERED_SECTIONS = ("camera", "scenario")


def check_set_values(overrides: Mapping[str, Any], settings: tuple[RenderSetting, ...]) -> None:
    """A one-line ConfigError where the nested `overrides` (`avsim.cli.overrides.parse_set`) give a key the benchmark
    does not read, one its frame set or one of `settings` sets, or a bad value (module docstring)."""
    for section, table in overrides.items():
        if section not in RENDERED_SECTIONS or not isinstance(table, Mapping):
            raise ConfigError(f"--set {section}.*: the realism benchmark draws its frames from camera and scenario keys "
                              f"and scores them with the --networks it names, so no frame reads {section} keys; give "
                              "camera.* or scenario.* keys")
    keys = dotted_keys(overrides)
    drawn = keys & set(FRAME_SET_KEYS)
    if drawn:
        raise ConfigError(f"--set {', '.join(sorted(drawn))}: every scene draw of the benchmark sets it (docs/realism.md, "
                          "the frame set); choose the towns with --towns and the draws with --seed")
    for setting in settings:
        clash = keys & dotted_keys(setting.config_overrides())
        if clash:
            raise ConfigError(f"--set {', '.join(sorted(clash))}: --settings {setting.name} sets it too, so the --set "
                              "would undo part of that setting; drop it from --settings or the --set")
        try:
            with_overrides(with_overrides(SimConfig(), setting.config_overrides()), overrides)
        except ConfigError as exc:
            raise ConfigError(f"--set under --settings {setting.name}: {exc}") from None
