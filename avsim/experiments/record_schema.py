"""Field-by-field checks of a run record read back from a results file (`--resume`).

A record edited by hand, or written by something else, must not be resumed as a finished
run: a NaN where a distance belongs, a string for a seed, a null outcome or a negative time
would flow into the report as if a run had produced it. The types come from the code that
writes records: `RunResult`'s annotations for the result, and `RECORD_FIELDS` for the record
around it; `RESULT_RANGES` bounds the result's values that no run can put outside them.
Keys a record lacks are not required here (records written before a field existed resume;
`results_file` requires the keys every record has had).
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from typing import Any

from avsim.metrics import RunResult
from avsim.validation import Range

# The record's own fields (`avsim.experiments.run_task`) -> the types a value may have.
RECORD_FIELDS: dict[str, tuple[type, ...]] = {
    "experiment": (str,), "cell": (str,), "seed": (int,), "spec_hash": (str,), "status": (str,),
    "error": (str, type(None)), "result": (dict, type(None)), "trace": (dict, list, type(None)),
    "rrd": (str, type(None)), "wall_s": (float, type(None)), "point": (dict,),
}
# Result values no run can give outside these (times, speeds and the brake command of a physical run).
RESULT_RANGES: dict[str, Range] = {
    "time_to_stop_s": Range(0, unit="s"), "sim_time_s": Range(0, unit="s"), "peak_speed_mps": Range(0, unit="m/s"),
    "speed_at_brake_mps": Range(0, unit="m/s"), "max_brake": Range(0, 1),
}


def record_field_problem(record: dict[str, Any]) -> str | None:
    """What is wrong with one field of `record` (named), or None when every field is well typed."""
    for key, kinds in RECORD_FIELDS.items():
        if key in record and not _is(record[key], kinds):
            return f"its {key} is {record[key]!r}, not {_names(kinds)}"
    if not 0 <= record.get("seed", 0):
        return f"its seed is {record['seed']}, not a seed >= 0"
    nan = _non_finite(record)
    if nan is not None:
        return f"its {nan} is not a finite number"
    result = record.get("result")
    if record.get("status") == "ok" and isinstance(result, dict):
        hints = typing.get_type_hints(RunResult)
        for f in dataclasses.fields(RunResult):
            if f.name in result and not _matches(result[f.name], hints[f.name]):
                return f"its result.{f.name} is {result[f.name]!r}, not {_annotation_name(hints[f.name])}"
        for name, limits in RESULT_RANGES.items():
            if result.get(name) is not None and not limits.contains(result[name]):
                return f"its result.{name} is {result[name]!r}, not {limits.describe()}"
    return None


def _is(value: Any, kinds: tuple[type, ...]) -> bool:
    if isinstance(value, bool):
        return bool in kinds
    if float in kinds and isinstance(value, int):
        return True
    return isinstance(value, kinds)


def _matches(value: Any, annotation: Any) -> bool:
    """Whether a JSON value fits a RunResult annotation (float accepts an int; lists are checked item by item)."""
    options = typing.get_args(annotation) if isinstance(annotation, types.UnionType) else (annotation,)
    for option in options:
        origin = typing.get_origin(option)
        if option is type(None) and value is None:
            return True
        if origin is list and isinstance(value, list):
            (item,) = typing.get_args(option)
            if all(_matches(v, item) for v in value):
                return True
        elif origin is dict and isinstance(value, dict):
            return True
        elif option in (float, int, str, bool) and _is(value, (option,)):
            return True
    return False


def _non_finite(value: Any, where: str = "") -> str | None:
    """The dotted place of the first NaN or infinity in `value`, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "value"
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = ((f"[{i}]", v) for i, v in enumerate(value))
    else:
        return None
    for key, item in items:
        place = _non_finite(item, f"{where}{key}" if str(key).startswith("[") else f"{where}.{key}" if where else str(key))
        if place is not None:
            return place
    return None


def _names(kinds: tuple[type, ...]) -> str:
    return " or ".join("null" if k is type(None) else "a number" if k is float else k.__name__ for k in kinds)


def _annotation_name(annotation: Any) -> str:
    return str(annotation).replace("NoneType", "null").replace("typing.", "")
