"""One validation layer for every number a user can give.

A `Range` declares the values a number may take, with its unit. It is declared once, next to
what it limits, and every way in shares it:

- config fields (`avsim.config`) declare theirs as dataclass field metadata with `ranged`, so
  `with_overrides`, `--set`, experiment and sweep files, `--from` records and direct
  construction all go through `check_ranges`, and a generated config reference can read them
  with `field_range`;
- command-line flags, of `avsim` and of every `python -m avsim....` entry point, use
  `number_flag` / `number_list_flag` / `name_list_flag` as their argparse `type`, so a bad
  value is refused by argparse in one line, exit 2, before any work;
- other keyword sets (an attack's hyperparameters) keep a table of Ranges and call `Range.check`.

NaN and infinity are never in a range. A refusal is one `ConfigError` line: the name, the
range with its unit, and the value given, e.g.
    scenario.speed_kmh must be in (0, 200] km/h, got nan
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from avsim.errors import ConfigError

# dataclasses.field metadata key under which `ranged` stores a field's Range.
RANGE_KEY = "avsim_range"


@dataclass(frozen=True)
class Range:
    """The values a number may take: lo .. hi (None: unbounded), each end open or closed.

    integer: only ints (no bool, no float) are accepted. unit: printed after the range
    ("km/h", "m", "px"). note: a short reason printed in brackets (e.g. "the approach road is 300 m").
    """

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False
    unit: str = ""
    note: str = ""

    def describe(self) -> str:
        """E.g. "in (0, 200] km/h", "an integer >= 1"."""
        kind = "an integer" if self.integer else ""
        fmt = lambda v: f"{v:g}" if isinstance(v, float) else str(v)  # noqa: E731
        if self.lo is not None and self.hi is not None:
            text = f"{kind} in {'(' if self.lo_open else '['}{fmt(self.lo)}, {fmt(self.hi)}{')' if self.hi_open else ']'}"
        elif self.lo is not None:
            text = f"{kind} {'>' if self.lo_open else '>='} {fmt(self.lo)}"
        elif self.hi is not None:
            text = f"{kind} {'<' if self.hi_open else '<='} {fmt(self.hi)}"
        else:
            text = f"a finite {'integer' if self.integer else 'number'}"
        text = text.strip()
        if self.unit:
            text += f" {self.unit}"
        if self.note:
            text += f" ({self.note})"
        return text

    def contains(self, value: Any) -> bool:
        """Whether `value` is a number of the right kind, finite and inside the range."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if self.integer and not isinstance(value, int):
            return False
        if not math.isfinite(value):
            return False
        if self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo):
            return False
        if self.hi is not None and (value >= self.hi if self.hi_open else value > self.hi):
            return False
        return True

    def check(self, value: Any, name: str) -> Any:
        """`value` unchanged, or a one-line ConfigError naming `name`, the range and the value."""
        if not self.contains(value):
            raise ConfigError(f"{name} must be {self.describe()}, got {value!r}")
        return value


def ranged(default: Any, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           hi_open: bool = False, unit: str = "", note: str = "") -> Any:
    """A dataclass field with `default` whose values are limited to a Range (see `check_ranges`).

    The field's annotation decides int or float: an int default declares an integer range.
    """
    spec = Range(lo, hi, lo_open, hi_open, integer=type(default) is int, unit=unit, note=note)
    if not spec.contains(default):
        raise ValueError(f"default {default!r} is outside its own range {spec.describe()}")
    return dataclasses.field(default=default, metadata={RANGE_KEY: spec})


def check_span(value: Any, name: str, bounds: Range) -> tuple[float, float]:
    """A (lo, hi) pair with lo <= hi, each inside `bounds`, as a tuple; a one-line ConfigError naming `name` if not.
    A range a value is drawn uniformly from (a view bank's sun elevation, a photometric gain)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ConfigError(f"{name} must be a pair [lo, hi], each {bounds.describe()}, got {value!r}")
    lo, hi = (bounds.check(item, name) for item in value)
    if lo > hi:
        raise ConfigError(f"{name} must be a pair [lo, hi] with lo <= hi, got {list(value)}")
    return lo, hi


def field_range(cls_or_instance: Any, name: str) -> Range | None:
    """The Range declared for dataclass field `name`, or None."""
    for f in dataclasses.fields(cls_or_instance):
        if f.name == name:
            return f.metadata.get(RANGE_KEY)
    raise KeyError(name)


def declared_ranges(cls_or_instance: Any) -> dict[str, Range]:
    """Every ranged field of a dataclass: name -> Range (for a generated reference, and tests)."""
    return {f.name: f.metadata[RANGE_KEY] for f in dataclasses.fields(cls_or_instance) if RANGE_KEY in f.metadata}


def check_ranges(instance: Any, section: str) -> None:
    """Check every ranged field of the dataclass `instance`; a field that is None and may be
    (an `X | None` annotation) is skipped. Raises a one-line ConfigError naming `section.field`."""
    for name, spec, optional in _ranged_fields(type(instance)):
        value = getattr(instance, name)
        if value is None and optional:
            continue
        spec.check(value, f"{section}.{name}")


@functools.cache
def _ranged_fields(cls: type) -> tuple[tuple[str, Range, bool], ...]:
    """(name, Range, may be None) of each ranged field of `cls`; cached, as configs are built per run."""
    hints = typing.get_type_hints(cls)
    return tuple((name, spec, type(None) in typing.get_args(hints[name])) for name, spec in declared_ranges(cls).items())


def check_finite_tree(value: Any, name: str) -> None:
    """Refuse NaN or infinity anywhere inside nested lists and mappings (a record, a file's table)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{name} must be a finite number, got {value!r}")
    if isinstance(value, dict):
        for key, item in value.items():
            check_finite_tree(item, f"{name}.{key}")
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            check_finite_tree(item, f"{name}[{index}]")


# ---- command-line flags --------------------------------------------------------------------

def _parse_number(text: str, integer: bool) -> int | float:
    # Python's int() and float() also take "1_00" and other scripts' digits ("٤٠"), which --set (TOML) refuses:
    # a flag reads only what its config key would.
    if not text.isascii() or "_" in text:
        raise argparse.ArgumentTypeError(f"expects {'an integer' if integer else 'a number'} in ASCII digits without "
                                         f"underscores, got '{text}'")
    try:
        return int(text) if integer else float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expects {'an integer' if integer else 'a number'}, got '{text}'") from None


def number_flag(lo: float | None = None, hi: float | None = None, *, integer: bool = False, lo_open: bool = False,
                hi_open: bool = False, unit: str = "", note: str = "") -> Callable[[str], int | float]:
    """An argparse `type` for a number flag limited to a Range: argparse refuses NaN, infinity
    and values outside it in one line, exit 2, before the command runs."""
    spec = Range(lo, hi, lo_open, hi_open, integer, unit, note)

    def parse(text: str) -> int | float:
        value = _parse_number(text, integer)
        if not spec.contains(value):
            raise argparse.ArgumentTypeError(f"must be {spec.describe()}, got {text}")
        return value

    parse.__name__ = "integer" if integer else "number"  # argparse names the type in some messages
    parse.range = spec  # type: ignore[attr-defined]
    return parse


def number_list_flag(lo: float | None = None, hi: float | None = None, *, integer: bool = False, lo_open: bool = False,
                     hi_open: bool = False, unit: str = "", note: str = "") -> Callable[[str], list[int | float]]:
    """An argparse `type` for comma-separated numbers ("0.05,0.1"), each within the Range, at
    least one, none repeated."""
    spec = Range(lo, hi, lo_open, hi_open, integer, unit, note)

    def parse(text: str) -> list[int | float]:
        items = [item.strip() for item in text.split(",")]
        if not any(items):
            raise argparse.ArgumentTypeError(f"expects comma-separated numbers, e.g. 0.05,0.1; got '{text}'")
        values = []
        for item in items:
            if not item:
                raise argparse.ArgumentTypeError(f"has an empty item in '{text}'; separate numbers by single commas")
            value = _parse_number(item, integer)
            if not spec.contains(value):
                raise argparse.ArgumentTypeError(f"each value must be {spec.describe()}, got {item}")
            if value in values:
                raise argparse.ArgumentTypeError(f"lists {item} twice")
            values.append(value)
        return values

    parse.__name__ = "number list"
    return parse


def name_list_flag(choices: Sequence[str] | None = None) -> Callable[[str], list[str]]:
    """An argparse `type` for comma-separated names ("town07,town03"): at least one, none
    empty or repeated, each one of `choices` when given."""

    def parse(text: str) -> list[str]:
        names = [name.strip() for name in text.split(",")]
        if not any(names):
            raise argparse.ArgumentTypeError(f"expects comma-separated names, got '{text}'")
        if not all(names):
            raise argparse.ArgumentTypeError(f"has an empty name in '{text}'; separate names by single commas")
        for name in names:
            if choices is not None and name not in choices:
                raise argparse.ArgumentTypeError(f"unknown name '{name}'; choose from {', '.join(choices)}")
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise argparse.ArgumentTypeError(f"lists '{repeated[0]}' twice")
        return names

    parse.__name__ = "name list"
    return parse


class OneLineArgumentParser(argparse.ArgumentParser):
    """argparse with its own errors (an unknown flag, a value out of range) in one line, exit 2,
    as avsim's are; for `avsim` and every `python -m avsim....` entry point."""

    def error(self, message: str) -> typing.NoReturn:
        """Print argparse's complaint as one line that points to --help, and exit 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def config_flag(cls: Any, name: str) -> Callable[[str], int | float]:
    """An argparse `type` with the Range of config field `cls.name` (`--speed-kmh` shares
    scenario.speed_kmh's), so a flag and its config key can never disagree."""
    spec = field_range(cls, name)
    if spec is None:
        raise ValueError(f"{cls.__name__}.{name} declares no range")
    return number_flag(spec.lo, spec.hi, integer=spec.integer, lo_open=spec.lo_open, hi_open=spec.hi_open,
                       unit=spec.unit, note=spec.note)
