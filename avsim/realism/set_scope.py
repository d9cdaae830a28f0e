"""Which `--set KEY=VALUE` a measurement command takes: the keys its frames or scores read, less those it sets
itself, each checked under every render setting it runs.

A measurement (`avsim realism`, `avsim attack eval`) builds its configs from the defaults, a render setting's values
and the keys it varies itself (a town, a sign, a drive's daylight). A `--set` there is laid over the defaults under
each setting, and is refused in one line before anything renders where it would mislead:
- a key the command never reads: it would change nothing the report shows;
- a key the command sets itself: the command's own value would win, silently;
- a key a chosen setting sets: the `--set` would quietly undo part of that setting;
- an unknown key or a bad value, checked under every setting.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from avsim.config_owners import dotted_keys
from avsim.errors import ConfigError
from avsim.realism.settings import RenderSetting


@dataclass(frozen=True)
class SetScope:
    """What one command's `--set` may give.

    reads: dotted prefixes of the keys the command reads ("camera." for a whole section, "policy.conf_threshold"
    for one key); reads_in_words: the same for a message ("camera and scenario keys"); own_keys: the dotted keys the
    command sets itself; own_fix: how to choose those instead (a message's end, e.g. "choose the towns with
    --towns"); command: the command's name in a message ("the realism benchmark"); setting_flag: its flag that
    chooses the render settings ("--settings").
    """

    reads: tuple[str, ...]
    reads_in_words: str
    own_keys: tuple[str, ...]
    own_fix: str
    command: str
    setting_flag: str = "--setting"

    def check(self, overrides: Mapping[str, Any], settings: tuple[RenderSetting, ...]) -> None:
        """A one-line ConfigError where the nested `overrides` (`avsim.cli.overrides.parse_set`) give a key this
        command does not read, one it or one of `settings` sets, or a bad value (module docstring)."""
        for section, table in overrides.items():
            if not isinstance(table, Mapping):
                raise ConfigError(f"--set {section}: a key names its section and the key (camera.fovy_deg=40); "
                                  f"{self.command} reads {self.reads_in_words}")
        keys = dotted_keys(overrides)
        unread = sorted(key for key in keys if not key.startswith(self.reads))
        if unread:
            raise ConfigError(f"--set {', '.join(unread)}: {self.command} reads {self.reads_in_words} only, so "
                              f"nothing it reports would change; give one of those")
        own = keys & set(self.own_keys)
        if own:
            raise ConfigError(f"--set {', '.join(sorted(own))}: {self.command} sets it itself; {self.own_fix}")
        for setting in settings:
            clash = keys & setting.keys
            if clash:
                raise ConfigError(f"--set {', '.join(sorted(clash))}: {self.setting_flag} {setting.name} sets it too, so "
                                  f"the --set would undo part of that setting; drop it from {self.setting_flag} or "
                                  "the --set")
            try:
                setting.config(overrides)
            except ConfigError as exc:
                raise ConfigError(f"--set under {self.setting_flag} {setting.name}: {exc}") from None
