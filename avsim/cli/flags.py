"""Flags several `avsim` commands share: the scenario flags and `--set`, and the config they make.

The command modules import this (and nothing of the simulator) at the top, so `avsim --help`
stays fast and the renderer is checked before MuJoCo is imported (`avsim.cli.command`).
"""

from __future__ import annotations

import argparse
from typing import Any

from avsim.cli.overrides import merge_overrides, parse_set
from avsim.config import LoopConfig, ScenarioConfig
from avsim.config_owners import dotted_keys
from avsim.errors import ConfigError
from avsim.outputs import add_input_argument
from avsim.realism.settings import BASELINE, SETTINGS, RenderSetting
from avsim.validation import config_flag, number_flag

SEED_FLAG = config_flag(ScenarioConfig, "seed")
WORKERS_FLAG = number_flag(1, 1024, integer=True)
BATCH_FLAG = number_flag(1, 1024, integer=True)
# `avsim reproduce --seeds N`: seeds per cell (the plan's size is checked as a whole, `plan_size`).
SEEDS_FLAG = number_flag(1, 10_000, integer=True)
# A finite integer whose range the command's own config declares (e.g. DataGenConfig, checked before any work).
INT_FLAG = number_flag(integer=True)


def add_scenario_flags(parser: argparse.ArgumentParser) -> None:
    """The flags of a command that builds a scenario: --town, --placement, --sign, --speed-kmh, --seed,
    --physics-dt-s, --control-dt-s and --set KEY=VALUE.
    """
    parser.add_argument("--town", help="town name (town03, town07, town10)")
    parser.add_argument("--placement", help="stop-sign placement: standard, near or far")
    add_input_argument(parser, "--sign", help="stop-sign texture: 'clean', a name in textures/, a PNG path, or 'none' (no stop sign)")
    parser.add_argument("--speed-kmh", type=config_flag(ScenarioConfig, "speed_kmh"), help="cruise speed [km/h]")
    parser.add_argument("--seed", type=SEED_FLAG, help="random seed (start jitter)")
    parser.add_argument("--physics-dt-s", type=config_flag(LoopConfig, "physics_dt_s"), help="physics step [s] (default 0.002)")
    parser.add_argument("--control-dt-s", type=config_flag(LoopConfig, "control_dt_s"), help="control and sensing period [s] (default 0.05)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override any config key, e.g. --set policy.baseline_brake=0.9 (repeatable)")


def flag_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The scenario flags and --set as one nested override mapping (--set wins over flags)."""
    flags = {
        "scenario": {"town": args.town, "placement": args.placement, "sign": args.sign, "speed_kmh": args.speed_kmh, "seed": args.seed},
        "loop": {"physics_dt_s": args.physics_dt_s, "control_dt_s": args.control_dt_s},
        "policy": {"name": getattr(args, "policy", None)},
        "perception": {"kind": getattr(args, "perception", None)},
    }
    overrides = {section: {k: v for k, v in values.items() if v is not None} for section, values in flags.items()}
    return merge_overrides(overrides, parse_set(args.set))


def config_from_args(args: argparse.Namespace, setting: RenderSetting | None = None):
    """The `SimConfig` the scenario flags and --set describe, over the defaults and over `setting`
    (`avsim run --setting`); a key both set is a one-line ConfigError (`refuse_setting_clash`)."""
    overrides = flag_overrides(args)
    refuse_setting_clash(setting, overrides)
    return (setting or SETTINGS[BASELINE]).config(overrides)


def refuse_setting_clash(setting: RenderSetting | None, overrides: dict[str, Any]) -> None:
    """A one-line ConfigError where the flags' `overrides` set a key that the render `setting` sets:
    the flags would quietly undo part of the setting the user asked for."""
    if setting is None:
        return
    clash = setting.keys & dotted_keys(overrides)
    if clash:
        raise ConfigError(f"{', '.join(sorted(clash))} is set by --setting {setting.name} and again by the flags; "
                          "leave out one of them")


def add_setting_flag(parser: argparse.ArgumentParser, what: str, refused: str) -> None:
    """--setting NAME: one of `avsim realism`'s render settings under `what` (`avsim.experiments.render_setting`);
    `refused` says which of the user's own keys it may not meet."""
    parser.add_argument("--setting", choices=tuple(SETTINGS), default=BASELINE, metavar="NAME",
                        help=f"render {what} under one of `avsim realism`'s settings, as if its keys stood in the file's "
                             f"[defaults]: {', '.join(SETTINGS)} (default {BASELINE}, the default renders; "
                             f"docs/realism.md); {refused}")


def add_set_flag(parser: argparse.ArgumentParser, what: str, refused: str) -> None:
    """--set KEY=VALUE (repeatable) on a batch command: one config value under `what`
    (`avsim.experiments.set_overrides`); `refused` says which keys it may not be given."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help=f"give {what} this config value, as if it stood in the file's [defaults], e.g. --set "
                             f"policy.conf_threshold=0.55 (repeatable; docs/reproducing.md); {refused}; a --resume "
                             "must give the same values")
