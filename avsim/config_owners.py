"""Every `policy.*` and `perception.*` config key has an owner: the policies and perceptions that read it.

`PolicyConfig` holds the keys of every braking policy and `PerceptionConfig` those of every
perception, so a key can be set where it has no effect (`policy.vote_k` under `baseline`). Each
registered policy declares the policy keys it reads (`BrakingPolicy.config_keys`) and each
perception kind its perception keys (`avsim.perception.factory.perception_keys`, some read only
under one value of another key: `coco_upscale` only with `coco_input = upscale`). A key that a
user *sets* and that no part of the run reads is refused before any work, in one line naming
the key and who does read it (a `ConfigError`, exit 2).

"Sets" means written by the user; a default is never refused. Where a key is written decides
which runs must read it:
- `avsim run`: a `--set` key (or a flag such as `--policy`) must be read by the run;
- an experiment file (`avsim.experiments.spec`): a key in a cell must be read by that cell; a
  key in `[defaults]` or `[vary]` applies to every cell and is refused only when no cell reads
  it (a `[defaults]` vote_k is for the cells of `temporal_vote`, and harmless to the others);
- a sweep file (`avsim.experiments.sweep`): a key in `[defaults]` or a grid axis is refused when
  no run of the grid reads it; and grid points that differ only in keys their runs do not read
  would be the same run twice, which is refused too (`identical_runs`), as the sweep already
  refuses two names of one texture: give such a policy its own sweep file;
- a leaderboard file: a defence's keys must be read by its runs; `[defaults]` keys by some run;
- the Gymnasium environment: a perception key of `config_overrides` must be read by its
  perception (the agent takes the policy's place, so policy keys are not checked).
- `avsim detect` and `avsim replay` run a perception on image files or a bag's images, outside the
  closed loop: no policy, scenario, vehicle, camera or loop key is read, and of the perception's
  keys not the simulated sensor's (`check_read_on_images`).
Not checked yet: `avsim snapshot`, whose `--set` builds a scene picture.

The map's keys (`MAP_KEYS`: `scenario.map_error`, `scenario.map_stop_line_offset_m`) change only
the HD map, which only the policies that declare `uses_map` read: they are owned by those policies.
The other `scenario`, `vehicle`, `camera` and `loop` keys are read by every run and not checked here.
`docs/config.md` (`python -m avsim.config_reference`) lists every key with its readers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any

from avsim.config import ENSEMBLE_NETWORKS, PerceptionConfig, PolicyConfig, ScenarioConfig, SimConfig
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.perception.factory import CONDITIONAL_KEYS, NETWORK_KEYS, PERCEPTION_KEYS, PERCEPTIONS, perception_keys

OWNED_SECTIONS = ("policy", "perception")
# Scenario keys that change only the HD map (`avsim.world.hd_map`), read by map-reading policies alone.
MAP_KEYS = ("scenario.map_error", "scenario.map_stop_line_offset_m")
# Keys every run reads, whatever its policy and perception, and why: the two that choose them, and
# the threshold by which the result record counts a confident stop-sign detection
# (`first_detection_dist_m`, the trace's `top_stop_conf`, the video's boxes; `avsim.loop`).
EVERY_RUN_READS = {
    "policy.name": "it names the braking policy",
    "perception.kind": "it names the perception",
    "policy.conf_threshold": "the result record's confident detection: first_detection_dist_m, the trace, the video",
}


def policy_reads(name: str) -> frozenset[str]:
    """The dotted `policy.*` keys the policy registered as `name` reads (with the every-run ones), and
    the map's keys when it reads the map."""
    policy = POLICIES.get(name)
    keys = frozenset(f"policy.{key}" for key in policy.config_keys) | _every_run("policy")
    return keys | frozenset(MAP_KEYS) if policy.uses_map else keys


def perception_reads(perception: PerceptionConfig) -> frozenset[str]:
    """The dotted `perception.*` keys the perception of `perception` reads (with the every-run ones)."""
    PERCEPTIONS.get(perception.kind)  # an unknown kind is refused as such
    return frozenset(f"perception.{key}" for key in perception_keys(perception)) | _every_run("perception")


def keys_read(config: SimConfig) -> frozenset[str]:
    """Every owned dotted key (`policy.*`, `perception.*`, `MAP_KEYS`) that the run of `config` reads."""
    return policy_reads(config.policy.name) | perception_reads(config.perception)


def _every_run(section: str) -> frozenset[str]:
    return frozenset(key for key in EVERY_RUN_READS if key.startswith(f"{section}."))


def set_keys(overrides: Mapping[str, Any]) -> frozenset[str]:
    """The owned dotted keys (`policy.*`, `perception.*`, `MAP_KEYS`) that a nested override mapping sets."""
    keys = set()
    for section in OWNED_SECTIONS:
        table = overrides.get(section)
        if isinstance(table, Mapping):
            keys.update(f"{section}.{key}" for key in table)
    scenario = overrides.get("scenario")
    if isinstance(scenario, Mapping):
        keys.update(f"scenario.{key}" for key in scenario if f"scenario.{key}" in MAP_KEYS)
    return frozenset(keys)


def readers(dotted: str) -> str:
    """Who reads `dotted`, in words: "policy temporal_vote", "perception coco or an ensemble with
    coco, with perception.coco_input = upscale", "every run (it names the braking policy)"."""
    section, key = dotted.split(".", 1)
    if dotted in MAP_KEYS:
        return f"the policies that read the map ({', '.join(_map_readers())})"
    if section == "policy":
        names = [name for name in POLICIES.names() if key in POLICIES.get(name).config_keys]
        policies = f"polic{'ies' if len(names) > 1 else 'y'} {', '.join(names)}" if names else "no policy"
        if dotted in EVERY_RUN_READS:
            return f"every run ({EVERY_RUN_READS[dotted]})" + (f"; and {policies} brake by it" if names else "")
        return policies
    if dotted in EVERY_RUN_READS:
        return f"every run ({EVERY_RUN_READS[dotted]})"
    kinds = [kind for kind, keys in PERCEPTION_KEYS.items() if key in keys or _conditional_on(key, keys)]
    members = [kind for kind in ENSEMBLE_NETWORKS if key in NETWORK_KEYS[kind] or _conditional_on(key, NETWORK_KEYS[kind])]
    text = f"perception{'s' if len(kinds) > 1 else ''} {', '.join(sorted(kinds))}" if kinds else "no perception"
    if members and "ensemble" not in kinds:
        text += f", or an ensemble with {' or '.join(members)} in perception.ensemble_members"
    if key in CONDITIONAL_KEYS:
        switch, value = CONDITIONAL_KEYS[key]
        text += f", with perception.{switch} = {value}"
    return text


def _map_readers() -> list[str]:
    return [name for name in POLICIES.names() if POLICIES.get(name).uses_map]


def _conditional_on(key: str, keys: Iterable[str]) -> bool:
    """Whether `key` is read under one value of a key in `keys` (purify_jpeg_quality under purify)."""
    return key in CONDITIONAL_KEYS and CONDITIONAL_KEYS[key][0] in keys


def _this_run(config: SimConfig, dotted: str) -> str:
    """What the run has that keeps it from reading `dotted`, e.g. "policy is baseline"."""
    section, key = dotted.split(".", 1)
    if section == "policy" or dotted in MAP_KEYS:
        return f"policy is {config.policy.name}"
    text = f"perception is {config.perception.kind}"
    if key in CONDITIONAL_KEYS:
        switch = CONDITIONAL_KEYS[key][0]
        text += f" with perception.{switch} = {getattr(config.perception, switch)}"
    return text


def _owned(dotted: str) -> bool:
    return dotted.split(".", 1)[0] in OWNED_SECTIONS or dotted in MAP_KEYS


def check_read(config: SimConfig, keys: Iterable[str]) -> None:
    """Refuse the first of `keys` (dotted) that the run of `config` does not read, in one line."""
    read = keys_read(config)
    unread = sorted(key for key in keys if _owned(key) and key not in read)
    if unread:
        key = unread[0]
        raise ConfigError(f"{key} is read only by {readers(key)}, and this run's {_this_run(config, key)}, so it "
                          f"would be ignored; remove it, or {_fix(config, key)}")


def _fix(config: SimConfig, dotted: str) -> str:
    """How to make the run read `dotted`: set the key it depends on, or choose another owner."""
    section, key = dotted.split(".", 1)
    if key in CONDITIONAL_KEYS and section == "perception":
        switch, value = CONDITIONAL_KEYS[key]
        if f"perception.{switch}" in keys_read(config):
            return f"set perception.{switch} = {value}"
    return f"choose a {'policy' if dotted in MAP_KEYS else section} that reads it"


# Perception keys that only a simulated camera gives meaning to: `avsim detect` searches a whole
# image file, with no range limit; `avsim replay` reads a bag's clean renders, regions included.
DETECT_UNREAD = ("perception.sensor_noise_std", "perception.min_box_height_px", "perception.front_roi_px",
                 "perception.side_roi_px")
REPLAY_UNREAD = ("perception.sensor_noise_std",)


def check_only_perception_keys(overrides: Mapping[str, Any], command: str) -> None:
    """Refuse, in one line, the first key of the nested `overrides` outside `perception`: a perception
    run on images (`command`, e.g. "avsim detect") reads no other."""
    for section, table in overrides.items():
        if section != "perception" and isinstance(table, Mapping) and table:
            key = f"{section}.{next(iter(table))}"
            raise ConfigError(f"{key} is not read by {command}, which runs a perception on images without a "
                              f"simulation; remove it (only perception.* keys apply)")


def check_read_on_images(perception: PerceptionConfig, perception_overrides: Mapping[str, Any], command: str,
                         unread: Iterable[str]) -> None:
    """Refuse, in one line, the first key of `perception_overrides` (the `perception` table a user
    set) that `perception`, run on images by `command`, does not read: one its kind does not read,
    or one of `unread` (DETECT_UNREAD, REPLAY_UNREAD)."""
    read = perception_reads(perception) - frozenset(unread)
    for key in sorted(set_keys({"perception": perception_overrides})):
        if key not in read:
            why = ("a simulated camera's setting" if key in unread
                   else f"read only by {readers(key)}, and the perception is {perception.kind}")
            raise ConfigError(f"{key} is not read by {command} ({why}), so it would be ignored; remove it")


def check_read_by_some(configs: Iterable[SimConfig], keys: Iterable[str], runs: str = "run") -> None:
    """Refuse the first of `keys` (dotted) that none of `configs` reads; runs: what a config is, in
    the message ("cell", "run of the grid")."""
    pending = {key for key in keys if _owned(key)}
    for config in configs:
        pending -= keys_read(config)
        if not pending:
            return
    if pending:
        key = sorted(pending)[0]
        raise ConfigError(f"{key} is read only by {readers(key)}, and no {runs} here has one, so it would be "
                          f"ignored; remove it, or choose a {'policy' if key in MAP_KEYS else key.split('.')[0]} "
                          f"that reads it")


def as_run(config: SimConfig) -> SimConfig:
    """`config` with every owned key its run does not read back at its default: two configs with
    the same `as_run` make the same run."""
    read = keys_read(config)
    policy = _defaults_for_unread(config.policy, PolicyConfig(), "policy", read)
    perception = _defaults_for_unread(config.perception, PerceptionConfig(), "perception", read)
    unread_map = {key.split(".", 1)[1]: getattr(ScenarioConfig(), key.split(".", 1)[1])
                  for key in MAP_KEYS if key not in read}
    scenario = dataclasses.replace(config.scenario, **unread_map)  # the defaults are valid with any scenario
    return dataclasses.replace(config, scenario=scenario, policy=policy, perception=perception)


def _defaults_for_unread(section: Any, default: Any, name: str, read: frozenset[str]) -> Any:
    unread = {f.name: getattr(default, f.name) for f in dataclasses.fields(section) if f"{name}.{f.name}" not in read}
    # Replacing one key at a time could pass through a combination __post_init__ refuses
    # (vote_k > vote_n); the defaults of every unread key together are valid with the read ones.
    return dataclasses.replace(section, **unread)


def identical_runs(labelled: Iterable[tuple[str, SimConfig]]) -> tuple[str, str, list[str]] | None:
    """The first two labels whose configs make the same run, with the keys in which they differ
    (read by neither); None when every config makes its own run."""
    seen: dict[SimConfig, tuple[str, SimConfig]] = {}
    for label, config in labelled:
        run = as_run(config)
        if run in seen:
            first_label, first = seen[run]
            differ = [f"{section}.{f.name}" for section in ("scenario", *OWNED_SECTIONS)
                      for f in dataclasses.fields(getattr(config, section))
                      if getattr(getattr(config, section), f.name) != getattr(getattr(first, section), f.name)]
            return first_label, label, differ
        seen[run] = (label, config)
    return None
