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
- `avsim snapshot` draws both cameras' pictures of a car placed at rest: it reads the scene's and
  the cameras' keys and its perception's, and no policy, loop or vehicle key
  (`check_snapshot_reads`).

A policy reads its keys only where it gets detections (a perception other than none through its
camera), but for its `blind_keys`, which act without one: the map-reading autopilot's, which never
gets a detection, and `map_prior`'s map stop; so `policy.baseline_brake` under perception none, and
`policy.conf_threshold` (read by every run that gets detections, `DETECTING_RUN_READS`) under the
autopilot, are refused.

The map's keys (`MAP_KEYS`: `scenario.map_error`, `scenario.map_stop_line_offset_m`) change only
the HD map, which only the policies that declare `uses_map` read: they are owned by those policies.
What a run draws decides which of the other `scenario`, `vehicle` and `camera` keys it reads
(`RUN_CONDITIONS`, judged on the run's `Sight`): a run draws through the cameras its policy uses
(the autopilot uses none, so its perception never runs) and a recorder draws the front camera
and the policy's; colour images only for a pixel perception or a recorder, segmentation only for
the oracle. So the side camera's keys are read only where the policy uses it, the sun, fog,
surfaces, photographic stages and a sign texture (not `scenario.sign = none`) only where colour is drawn, `camera.seg_supersample` only by the
oracle, `scenario.fog_start_m` only in fog, `scenario.seed` only with a start jitter or sensor
noise, and `vehicle.abs_target_slip` only with anti-lock brakes or traction control on. An experiment, sweep or leaderboard file's runs may be recorded
(a batch's `--rrd failed` is the default), so there a recorder is assumed; `avsim run` knows.
Every other key (the loop's, the car's, where and how fast it starts) is read by every run.
`docs/config.md` (`python -m avsim.config_reference`) lists every key with its readers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any

from avsim.config import ENSEMBLE_NETWORKS, CameraConfig, PerceptionConfig, SimConfig
from avsim.config_sight import RUN_CONDITIONS, Sight
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.perception.factory import CONDITIONAL_KEYS, NETWORK_KEYS, PERCEPTION_KEYS, PERCEPTIONS, perception_keys

OWNED_SECTIONS = ("policy", "perception")
# Scenario keys that change only the HD map (`avsim.world.hd_map`), read by map-reading policies alone.
MAP_KEYS = ("scenario.map_error", "scenario.map_stop_line_offset_m")
# Keys every run reads, whatever its policy and perception, and why: the two that choose them.
EVERY_RUN_READS = {
    "policy.name": "it names the braking policy",
    "perception.kind": "it names the perception",
}
# Keys every run that gets detections reads (a perception other than none, through a policy's
# camera), whatever its policy, and why: the threshold by which the result record counts a confident
# stop-sign detection (`first_detection_dist_m`, the trace's `top_stop_conf`, the video's boxes;
# `avsim.loop`). A run with no detection (the autopilot, or perception none) has none to count.
DETECTING_RUN_READS = {
    "policy.conf_threshold": "the result record's confident detection: first_detection_dist_m, the trace, the video",
}
# A pixel perception's region of interest in each camera, read only where it sees through that camera.
REGION_KEYS = {"front": "perception.front_roi_px", "side": "perception.side_roi_px"}


def policy_reads(name: str, *, detects: bool = True) -> frozenset[str]:
    """The dotted `policy.*` keys the policy registered as `name` reads (with the every-run ones), and
    the map's keys when it reads the map; detects: whether it gets detections (a perception other
    than none through its camera): without, only its `blind_keys` and no `DETECTING_RUN_READS`."""
    policy = POLICIES.get(name)
    own = policy.config_keys if detects else policy.blind_keys
    keys = frozenset(f"policy.{key}" for key in own) | _every_run("policy")
    keys |= frozenset(DETECTING_RUN_READS) if detects else frozenset()
    return keys | frozenset(MAP_KEYS) if policy.uses_map else keys


def perception_reads(perception: PerceptionConfig) -> frozenset[str]:
    """The dotted `perception.*` keys the perception of `perception` reads (with the every-run ones)."""
    PERCEPTIONS.get(perception.kind)  # an unknown kind is refused as such
    return frozenset(f"perception.{key}" for key in perception_keys(perception)) | _every_run("perception")


def _perception_seen(perception: PerceptionConfig, sight: Sight) -> frozenset[str]:
    """`perception_reads` less what no camera of the run feeds: every key but the every-run ones
    when it sees through no camera (the autopilot), a camera's region when it does not see through it."""
    if not sight.cameras:
        return _every_run("perception")
    return perception_reads(perception) - {key for camera, key in REGION_KEYS.items() if camera not in sight.cameras}


def keys_read(config: SimConfig, *, recorded: bool = True, cameras: tuple[str, ...] | None = None) -> frozenset[str]:
    """Every owned dotted key (`policy.*`, `perception.*`, `MAP_KEYS`, `RUN_CONDITIONS`) that the run
    of `config` reads; recorded: whether a recorder may draw it; cameras: those its perception sees
    through (None: its policy's)."""
    sight = Sight.of(config, recorded=recorded, cameras=cameras)
    conditional = frozenset(key for key, condition in RUN_CONDITIONS.items() if condition.holds(config, sight))
    policy = policy_reads(config.policy.name, detects=sight.perceives)
    return policy | _perception_seen(config.perception, sight) | conditional


def _every_run(section: str) -> frozenset[str]:
    return frozenset(key for key in EVERY_RUN_READS if key.startswith(f"{section}."))


def _owned(dotted: str) -> bool:
    """Whether `dotted` is read by some runs only (and so checked): a policy or perception key, the map's, or a RUN_CONDITIONS key."""
    return dotted.split(".", 1)[0] in OWNED_SECTIONS or dotted in MAP_KEYS or dotted in RUN_CONDITIONS


def dotted_keys(overrides: Mapping[str, Any]) -> frozenset[str]:
    """Every dotted key a nested override mapping sets ({"policy": {"vote_k": 3}} -> policy.vote_k)."""
    return frozenset(f"{section}.{key}" for section, table in overrides.items() if isinstance(table, Mapping) for key in table)


def set_keys(overrides: Mapping[str, Any]) -> frozenset[str]:
    """The owned dotted keys (`policy.*`, `perception.*`, `MAP_KEYS`, `RUN_CONDITIONS`) that a nested override mapping sets."""
    return frozenset(key for key in dotted_keys(overrides) if _owned(key))


def readers(dotted: str) -> str:
    """Who reads `dotted`, in words: "policy temporal_vote", "perception coco or an ensemble with
    coco, with perception.coco_input = upscale", "every run (it names the braking policy)"."""
    section, key = dotted.split(".", 1)
    if dotted in MAP_KEYS:
        return f"the policies that read the map ({', '.join(_map_readers())})"
    if dotted in RUN_CONDITIONS:
        return RUN_CONDITIONS[dotted].readers
    if section == "policy":
        names = [name for name in POLICIES.names() if key in POLICIES.get(name).config_keys]
        policies = f"polic{'ies' if len(names) > 1 else 'y'} {', '.join(names)}" if names else "no policy"
        if dotted in EVERY_RUN_READS:
            return f"every run ({EVERY_RUN_READS[dotted]})" + (f"; and {policies} brake by it" if names else "")
        if dotted in DETECTING_RUN_READS:
            return (f"every run that gets detections, from a perception other than none through its policy's camera "
                    f"({DETECTING_RUN_READS[dotted]})" + (f"; and {policies} brake by it" if names else ""))
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
    if dotted == REGION_KEYS["side"]:
        text += f", through the side camera (policies {', '.join(_camera_users('side'))})"
    return text


def _map_readers() -> list[str]:
    return [name for name in POLICIES.names() if POLICIES.get(name).uses_map]


def _camera_users(camera: str) -> list[str]:
    return [name for name in POLICIES.names() if camera in POLICIES.get(name).cameras]


def _conditional_on(key: str, keys: Iterable[str]) -> bool:
    """Whether `key` is read under one value of a key in `keys` (purify_jpeg_quality under purify)."""
    return key in CONDITIONAL_KEYS and CONDITIONAL_KEYS[key][0] in keys


def _unseen_camera(config: SimConfig, dotted: str, sight: Sight) -> str | None:
    """The camera whose absence alone keeps the run from reading the perception key `dotted`, which
    its perception's kind reads: "" when it sees through no camera, "side" for the side region;
    None when the cameras are not the reason."""
    if dotted in EVERY_RUN_READS or dotted not in perception_reads(config.perception):
        return None
    if not sight.cameras:
        return ""
    return next((camera for camera, key in REGION_KEYS.items() if key == dotted and camera not in sight.cameras), None)


def _this_run(config: SimConfig, dotted: str, sight: Sight) -> str:
    """What the run has that keeps it from reading `dotted`, e.g. "policy is baseline"."""
    section, key = dotted.split(".", 1)
    if dotted in RUN_CONDITIONS:
        return RUN_CONDITIONS[dotted].unmet(config, sight)
    if section == "policy" and not sight.perceives and dotted in policy_reads(config.policy.name):
        if not sight.cameras:
            return f"policy is {sight.policy}, which uses no camera, so it gets no detection"
        return f"perception is {sight.kind}, so policy {sight.policy} gets no detection"
    if section == "policy" or dotted in MAP_KEYS:
        return f"policy is {config.policy.name}"
    camera = _unseen_camera(config, dotted, sight)
    if camera is not None:
        if sight.agent:
            return f"perception sees through the {' and '.join(sight.cameras)} camera only"
        return f"policy is {sight.policy}, which " + ("uses no camera" if camera == "" else f"does not use the {camera} camera")
    text = f"perception is {config.perception.kind}"
    if key in CONDITIONAL_KEYS:
        switch = CONDITIONAL_KEYS[key][0]
        text += f" with perception.{switch} = {getattr(config.perception, switch)}"
    return text


def check_read(config: SimConfig, keys: Iterable[str], *, recorded: bool = True, cameras: tuple[str, ...] | None = None) -> None:
    """Refuse the first of `keys` (dotted) that the run of `config` does not read, in one line;
    recorded, cameras: as for `keys_read` (a recorder is assumed unless the caller knows better)."""
    read = keys_read(config, recorded=recorded, cameras=cameras)
    unread = sorted(key for key in keys if _owned(key) and key not in read)
    if unread:
        key = unread[0]
        sight = Sight.of(config, recorded=recorded, cameras=cameras)
        raise ConfigError(f"{key} is read only by {readers(key)}, and this run's {_this_run(config, key, sight)}, so it "
                          f"would be ignored; remove it, or {_fix(config, key, sight)}")
    _check_preset_fills_something(set(keys), read)


def _check_preset_fills_something(keys: set[str], read: frozenset[str]) -> None:
    """Refuse a `camera.preset` set beside every preset key the run reads: a preset only fills the
    keys left at 0 (`CameraConfig.PRESET_KEYS`), so it would fill none."""
    filled = [f"camera.{key}" for key in CameraConfig.PRESET_KEYS if f"camera.{key}" in read]
    if "camera.preset" in keys and all(key in keys for key in filled):
        raise ConfigError(f"camera.preset fills only the camera keys not set beside it, and {', '.join(filled)} "
                          f"{'is' if len(filled) == 1 else 'are'} all set here, so it would be ignored; remove it, or one of them")


def _fix(config: SimConfig, dotted: str, sight: Sight) -> str:
    """How to make the run read `dotted`: set the key it depends on, or choose another owner."""
    section, key = dotted.split(".", 1)
    if dotted in RUN_CONDITIONS:
        return RUN_CONDITIONS[dotted].fix
    if section == "policy" and not sight.perceives and dotted in policy_reads(config.policy.name):
        return "choose a perception other than none" if sight.cameras else "choose a policy that uses a camera"
    camera = _unseen_camera(config, dotted, sight)
    if camera is not None:
        return f"choose a policy that uses the {camera} camera" if camera else "choose a policy that uses a camera"
    if key in CONDITIONAL_KEYS and section == "perception":
        switch, value = CONDITIONAL_KEYS[key]
        if f"perception.{switch}" in _perception_seen(config.perception, sight):
            return f"set perception.{switch} = {value}"
    return _fix_any(dotted)


def _fix_any(dotted: str) -> str:
    """How to make some run read `dotted`: choose an owner, or meet its condition."""
    if dotted in RUN_CONDITIONS:
        return RUN_CONDITIONS[dotted].fix
    if dotted == REGION_KEYS["side"]:
        return "choose a pixel perception and a policy that uses the side camera"
    return f"choose a {'policy' if dotted in MAP_KEYS else dotted.split('.')[0]} that reads it"


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


# What `avsim snapshot` leaves unread: it places the car at rest at --dist-m (with no physics step)
# and draws both cameras in colour, with its perception's boxes. Dotted key or section -> why.
SNAPSHOT_UNREAD = {
    "policy": "it draws the cameras' pictures, and no policy decides anything",
    "loop": "it places the car at rest at --dist-m and runs no physics step",
    "vehicle": "it places the car at rest at --dist-m and runs no physics step",
    **dict.fromkeys(("scenario.speed_kmh", "scenario.start_speed_kmh", "scenario.start_dist_m", "scenario.start_jitter_m",
                     "scenario.road_friction"), "it places the car at rest at --dist-m and runs no physics step"),
    **dict.fromkeys(MAP_KEYS, "its pictures show the world, not the car's map"),
}


def check_snapshot_reads(config: SimConfig, overrides: Mapping[str, Any], *, towns: bool) -> None:
    """Refuse, in one line, the first key of the nested `overrides` (what a user set) that `avsim
    snapshot` of `config` does not read; towns: whether --towns names the towns (then scenario.town
    is not read)."""
    for key in sorted(dotted_keys(overrides)):
        why = _snapshot_unread(config, key, towns)
        if why:
            raise ConfigError(f"{key} is not read by avsim snapshot ({why}), so it would be ignored; remove it")


def _snapshot_unread(config: SimConfig, dotted: str, towns: bool) -> str | None:
    """Why `avsim snapshot` does not read `dotted`, or None when it does."""
    section = dotted.split(".", 1)[0]
    why = SNAPSHOT_UNREAD.get(dotted) or SNAPSHOT_UNREAD.get(section)
    if why:
        return why
    perception = perception_reads(config.perception)  # both cameras, so both regions
    if dotted == "scenario.town" and towns:
        return "--towns names the towns"
    if dotted == "scenario.seed" and not ("perception.sensor_noise_std" in perception and config.perception.sensor_noise_std > 0):
        return ("it seeds the start jitter, which --dist-m replaces, and a pixel perception's sensor noise, and this "
                f"perception ({config.perception.kind}) draws none")
    if section == "perception" and dotted not in perception:
        return f"read only by {readers(dotted)}, and the perception is {config.perception.kind}"
    if dotted == "camera.seg_supersample" and config.perception.kind != "oracle":
        return f"only the oracle perception draws segmentation, and the perception is {config.perception.kind}"
    if dotted == "scenario.fog_start_m" and config.scenario.fog_end_m == 0:
        return "scenario.fog_end_m is 0 (clear air: no fog is drawn)"
    return None


def check_read_by_some(configs: Iterable[SimConfig], keys: Iterable[str], runs: str = "run") -> None:
    """Refuse the first of `keys` (dotted) that none of `configs` reads (each run may be recorded);
    runs: what a config is, in the message ("cell", "run of the grid")."""
    pending = {key for key in keys if _owned(key)}
    for config in configs:
        pending -= keys_read(config)
        if not pending:
            return
    if pending:
        key = sorted(pending)[0]
        raise ConfigError(f"{key} is read only by {readers(key)}, and no {runs} here has one, so it would be "
                          f"ignored; remove it, or {_fix_any(key)}")


def as_run(config: SimConfig) -> SimConfig:
    """`config` with every owned key its run does not read (even recorded) back at its default: two
    configs with the same `as_run` make the same run."""
    read = keys_read(config)
    sections = {}
    for section in dataclasses.fields(config):
        value = getattr(config, section.name)
        default = type(value)()
        # Replacing one key at a time could pass through a combination __post_init__ refuses
        # (vote_k > vote_n); the defaults of every unread key together are valid with the read ones.
        unread = {f.name: getattr(default, f.name) for f in dataclasses.fields(value)
                  if _owned(f"{section.name}.{f.name}") and f"{section.name}.{f.name}" not in read}
        sections[section.name] = dataclasses.replace(value, **unread)
    return dataclasses.replace(config, **sections)


def identical_runs(labelled: Iterable[tuple[str, SimConfig]]) -> tuple[str, str, list[str]] | None:
    """The first two labels whose configs make the same run, with the keys in which they differ
    (read by neither); None when every config makes its own run."""
    seen: dict[SimConfig, tuple[str, SimConfig]] = {}
    for label, config in labelled:
        run = as_run(config)
        if run in seen:
            first_label, first = seen[run]
            differ = [f"{section.name}.{f.name}" for section in dataclasses.fields(config)
                      for f in dataclasses.fields(getattr(config, section.name))
                      if getattr(getattr(config, section.name), f.name) != getattr(getattr(first, section.name), f.name)]
            return first_label, label, differ
        seen[run] = (label, config)
    return None
