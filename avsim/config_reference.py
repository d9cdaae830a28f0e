"""`docs/config.md`, generated from the code: every config key with its unit, range, default,
what it means, and which policies or perceptions read it.

    python -m avsim.config_reference --out docs/config.md     # write it
    python -m avsim.config_reference --check docs/config.md   # exit 1 if it is stale

Each piece comes from where it is declared, so the page cannot drift from the code: the keys,
types and defaults from the dataclasses of `avsim.config`; ranges and units from their
`ranged()` metadata (`avsim.validation`); the choices of a name from the registries and the
constants `avsim.config` checks against; the meaning from the comments written beside each
field in `avsim/config.py`; the readers from `avsim.config_owners`.
"""

from __future__ import annotations

import dataclasses
import inspect
import io
import sys
import tokenize
import typing
from pathlib import Path
from typing import Any

from avsim import config as config_module
from avsim.boundary import run_guarded
from avsim.config import CameraConfig, SimConfig, type_name
from avsim.config_owners import DETECT_UNREAD, DETECTING_RUN_READS, EVERY_RUN_READS, MAP_KEYS, OWNED_SECTIONS, SNAPSHOT_UNREAD, readers
from avsim.config_sight import RUN_CONDITIONS
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.file_kinds import special_file_kind
from avsim.outputs import write_text
from avsim.perception.factory import PERCEPTIONS
from avsim.validation import RANGE_KEY, OneLineArgumentParser
from avsim.world.towns import PLACEMENTS, TOWNS

PROG = "python -m avsim.config_reference"
COMMAND = f"{PROG} --out docs/config.md"
# The names a string (or list) key may take, where the code checks them: dotted key -> choices.
CHOICES: dict[str, Any] = {
    "scenario.town": TOWNS.names(),
    "scenario.placement": PLACEMENTS.names(),
    "scenario.distractors": config_module.DISTRACTORS,
    "scenario.map_error": config_module.MAP_ERRORS,
    "scenario.materials": config_module.MATERIALS,
    "scenario.sign_materials": config_module.SIGN_MATERIALS,
    "scenario.foliage": config_module.FOLIAGES,
    "scenario.facade_windows": config_module.FACADE_WINDOWS,
    "scenario.sky": config_module.SKIES,
    "scenario.road_paint": config_module.ROAD_PAINTS,
    "scenario.sun_shadow_map_px": config_module.SHADOW_MAP_SIZES_PX,
    "camera.preset": tuple(config_module.CAMERA_PRESETS),
    "camera.offsamples": config_module.OFFSAMPLES,
    "camera.seg_supersample": config_module.SEG_SUPERSAMPLES,
    "camera.supersample": config_module.SUPERSAMPLES,
    "camera.texture_anisotropy": config_module.TEXTURE_ANISOTROPIES,
    "perception.kind": PERCEPTIONS.names(),
    "perception.detector_precision": config_module.PRECISIONS,
    "perception.coco_input": config_module.COCO_INPUTS,
    "perception.coco_precision": config_module.PRECISIONS,
    "perception.yolo_input": config_module.COCO_INPUTS,
    "perception.yolo_precision": config_module.PRECISIONS,
    "perception.purify": config_module.PURIFIERS,
    "perception.purify_median_kernel_px": config_module.MEDIAN_KERNELS_PX,
    "perception.ensemble_fusion": config_module.ENSEMBLE_FUSIONS,
    "perception.ensemble_members": config_module.ENSEMBLE_NETWORKS,
    "policy.name": POLICIES.names(),
}


def field_comments(cls: type) -> dict[str, str]:
    """The comments written beside each field of a dataclass: the comment lines right above it
    and a comment at the end of its line, joined into one text."""
    source = inspect.getsource(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    comments: dict[str, str] = {}
    pending: list[str] = []
    block = ""  # the last comment block above a field: one block may explain the fields below it too
    line_of_field: dict[int, str] = {}
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            text = token.string.lstrip("#").strip()
            if token.start[0] in line_of_field:  # at the end of a field's line
                name = line_of_field[token.start[0]]
                comments[name] = f"{comments.get(name, '')} {text}".strip()
            else:
                pending.append(text)
        elif token.type == tokenize.NAME and token.start[1] == 4 and token.string in names and token.start[0] not in line_of_field:
            line_of_field[token.start[0]] = token.string
            block = " ".join(pending) or block
            # A field with no comment of its own is explained by the block above when that names it
            # (fog_end_m by the fog block, the vote_* keys by temporal_vote's).
            comments[token.string] = " ".join(pending) or (block if token.string in block else "")
            pending = []
        elif token.type == tokenize.NAME and token.start[1] == 4:
            pending, block = [], ""  # a method or anything else at field indent ends a comment block
    return comments


def _type_name(annotation: Any) -> str:
    """As `avsim.config.type_name`, with "or none" for an optional field (`float | None`)."""
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if len(args) < len(typing.get_args(annotation)):
        return f"{type_name(args[0])} or none"
    return type_name(annotation)


def _value(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"'
    return f"{value:g}" if isinstance(value, float) else str(value)


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def section_table(section: str, instance: Any) -> list[str]:
    """The Markdown table lines of one config section (`section`, e.g. "camera", and its default
    dataclass `instance`): a row per key with type, unit, range or choices, default, readers, meaning."""
    cls = type(instance)
    hints = typing.get_type_hints(cls)
    comments = field_comments(cls)
    rows = ["| key | type | unit | range or choices | default | read by | meaning |", "|---|---|---|---|---|---|---|"]
    previous = ""
    for f in dataclasses.fields(cls):
        meaning = comments.get(f.name, "")
        meaning, previous = ("as the key above" if meaning and meaning == previous else meaning), meaning
        dotted = f"{section}.{f.name}"
        spec = f.metadata.get(RANGE_KEY)
        if spec is not None:
            limits, unit = dataclasses.replace(spec, unit="").describe(), spec.unit
        elif dotted in CHOICES:
            limits, unit = ", ".join(_value(c) for c in CHOICES[dotted]), ""
        else:
            limits, unit = "", ""
        who = readers(dotted) if section in OWNED_SECTIONS or dotted in MAP_KEYS or dotted in RUN_CONDITIONS else "every run"
        rows.append(f"| `{dotted}` | {_type_name(hints[f.name])} | {unit} | {_cell(limits)} | `{_value(getattr(instance, f.name))}` | "
                    f"{_cell(who)} | {_cell(meaning)} |")
    return rows


def generate() -> str:
    """The whole page, as Markdown."""
    lines = [
        "# Config reference",
        "",
        f"Generated from the code by `{COMMAND}`; `tests/test_config_reference.py` fails when this page is stale.",
        "Every key can be set with `avsim run --set KEY=VALUE`, in an experiment, sweep or leaderboard file, or in",
        "`config_overrides` of the Gymnasium environment ([running.md](running.md), [scaling.md](scaling.md)).",
        "An unknown key, a wrong type or a value out of range is refused before any work, naming the key.",
        "",
        "**Who reads a key.** A `policy.*` key is read only by the policies that declare it, and a `perception.*`",
        "key only by the perceptions that declare it, through the cameras its policy uses (the autopilot uses",
        "none; `avsim/config_owners.py`). The map's keys (" + ", ".join(f"`{key}`" for key in MAP_KEYS) + ") are read only by the",
        "policies that read the map. Some scenario, camera and vehicle keys are read only where the run draws",
        "what they change (`avsim/config_sight.py`): a perception draws through its policy's cameras, in colour",
        "for a pixel perception and as segmentation for the oracle, and a recorder draws the front camera and",
        "the policy's in colour; the read-by column says which. Every other scenario, vehicle, camera and loop key",
        "is read by every run. A key you set that the run does not read is refused, in one line naming the key",
        "and who reads it, exit 2; a default is never refused. `avsim run` knows whether it records; a file's runs",
        "may be recorded by its batch, so there a recorder is assumed. A `camera.preset` set beside every camera",
        "key it would fill (" + ", ".join(f"`camera.{key}`" for key in CameraConfig.PRESET_KEYS) + ", those the run reads) is refused too. A key in",
        "one cell of an experiment file (or one leaderboard defence) must be read by that cell; a key in",
        "`[defaults]`, `[vary]` or a sweep's grid applies to many runs and is refused only when none of them",
        "reads it. A sweep whose grid points differ only in keys their runs do not read would run one run twice",
        "under two labels, and is refused: give that policy its own sweep file. Keys every run reads, whatever",
        "its policy and perception: " + "; ".join(f"`{key}` ({why})" for key, why in EVERY_RUN_READS.items()) + ".",
        "Keys every run that gets detections reads (a perception other than none, through its policy's camera): "
        + "; ".join(f"`{key}` ({why})" for key, why in DETECTING_RUN_READS.items()) + ". A policy reads its other keys",
        "only where it gets detections, but for those that act without one (" + "; ".join(
            f"{name}: " + ", ".join(f"`policy.{key}`" for key in POLICIES.get(name).blind_keys)
            for name in POLICIES.names() if POLICIES.get(name).blind_keys) + "): perception none",
        "(or the autopilot, which uses no camera) gives a policy no detection.",
        "`avsim detect` and `avsim replay` run a perception on images without a simulation: they refuse every",
        "key but their perception's, and of those the simulated camera's (" + ", ".join(f"`{key}`" for key in DETECT_UNREAD)
        + "; a bag's frames keep their regions). `avsim snapshot` places the car at rest and draws both cameras in",
        "colour with its perception: it refuses the " + ", ".join(f"`{key}`" for key in SNAPSHOT_UNREAD if "." not in key)
        + " keys, " + ", ".join(f"`{key}`" for key in SNAPSHOT_UNREAD if "." in key) + ", its perception's unread keys,",
        "`camera.seg_supersample` unless the oracle draws, `scenario.seed` unless a pixel perception draws sensor noise",
        "and `scenario.town` with `--towns`.",
        "",
        "The meaning column is the comment written beside the field in `avsim/config.py`.",
        "",
    ]
    config = SimConfig()
    for f in dataclasses.fields(config):
        instance = getattr(config, f.name)
        lines += [f"## `{f.name}`", "", (type(instance).__doc__ or "").strip().splitlines()[0], ""]
        lines += section_table(f.name, instance) + [""]
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.config_reference`: print, write (--out) or check (--check) the page; returns the exit status."""
    parser = OneLineArgumentParser(prog=PROG, description="Write or check docs/config.md, the reference of every config key.")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--out", help="write the page here (default: print it)")
    group.add_argument("--check", metavar="PAGE", help="exit 1 if PAGE differs from what the code generates")
    args = parser.parse_args(argv)

    def command() -> int:
        page = generate()
        if args.check:
            path = Path(args.check)
            if not path.is_file():
                kind = "a folder" if path.is_dir() else special_file_kind(path)
                what = f"is {kind}, not a regular file" if kind else "does not exist"
                raise ConfigError(f"{path} {what}; write it with {COMMAND}")
            try:
                current = path.read_text(encoding="utf-8")
            except UnicodeDecodeError:  # not the page, nor any text it would be compared with
                current = None
            if current != page:
                print(f"{PROG}: {path} is stale; write it again with {COMMAND}", file=sys.stderr)
                return 1
            print(f"{path} is current")
        elif args.out:
            write_text(args.out, page)
            print(f"wrote {args.out}")
        else:
            sys.stdout.write(page)
        return 0

    return run_guarded(command, prog=PROG)


if __name__ == "__main__":
    raise SystemExit(main())
