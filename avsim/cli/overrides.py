"""`--set KEY=VALUE` overrides, as every subcommand that takes a config reads them.

A value is read as a TOML value (`0.9`, `true`, `[1, 2]`, `"text"`), and a bare word as a
string; dotted keys nest (`policy.name=adjusted` -> {"policy": {"name": "adjusted"}}).
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from typing import Any

from avsim.errors import ConfigError


def parse_set(items: Sequence[str]) -> dict[str, Any]:
    """Turn ["policy.baseline_brake=0.9", ...] into a nested override mapping."""
    overrides: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set expects KEY=VALUE (e.g. policy.baseline_brake=0.9), got '{item}'")
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw  # a bare word is a string
        node = overrides
        *parents, leaf = key.split(".")
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"--set {key} conflicts with an earlier --set that gave '{part}' a plain value")
        if isinstance(node.get(leaf), dict):
            raise ConfigError(f"--set {key} conflicts with an earlier --set of a key inside '{leaf}'")
        node[leaf] = value
    return overrides


def merge_overrides(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    """`extra` laid over `base`, nested mappings merged key by key (the later value wins)."""
    merged = dict(base)
    for key, value in extra.items():
        merged[key] = merge_overrides(merged[key], value) if isinstance(value, dict) and isinstance(merged.get(key), dict) else value
    return merged
