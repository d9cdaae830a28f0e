"""JSON-lines results files that survive crashes: one record per line, each flushed to disk.

Each record is written as one complete line, then fsynced; a write that fails (a full disk,
a file-size limit) is cut back to the last whole line at once, and a crash can leave at most
a torn *last* line; `read_records` skips such a line (it is a run
that never finished) and reads every complete one. Anything else that is not a run record
is refused in one line, never skipped: a corrupt line in the middle (named by its number),
or a file that is not avsim's at all (its first line is not a run record). A run record is
a JSON object with the keys of `RECORD_KEYS` and a status of "ok" or "failed". Files are
appended to, or replaced whole (`rewrite`: a temporary file renamed over them), never
rewritten in place.

Records written before the outcome labels were renamed (`stopped_before_sign`,
`stopped_past_sign`, `did_not_stop`) are read with today's label, recomputed from the
record's own distances (`avsim.metrics.classify_outcome`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from avsim.errors import ConfigError, OutputError
from avsim.experiments.record_schema import record_field_problem
from avsim.metrics import ALL_OUTCOMES, classify_outcome, write_text_atomic

RECORD_KEYS = ("experiment", "cell", "seed", "spec_hash", "status")
STATUSES = ("ok", "failed")
LEGACY_OUTCOMES = ("stopped_before_sign", "stopped_past_sign", "did_not_stop")


def encode(record: dict[str, Any]) -> str:
    """One record as one line (no NaN: JSON has none)."""
    return json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n"


class JsonlWriter:
    """Appends records to `path`, one durable line each."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def append(self, record: dict[str, Any]) -> None:
        """Append `record` as one line and fsync it; on a failed write (a full disk, a file-size
        limit) the file is cut back to its last whole line and an OutputError names it."""
        line = encode(record).encode()
        # O_APPEND: the line lands at the end. One writer per folder (`output_lock`), so the
        # length before the write is where a failed write is cut back to.
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            whole = os.fstat(fd).st_size
            try:
                written = 0
                while written < len(line):  # a write near a file-size limit can be short
                    written += os.write(fd, line[written:])
                os.fsync(fd)
            except OSError as exc:
                _cut_back(fd, whole)
                raise OutputError(f"cannot append to {self.path} ({exc.strerror or exc}); it keeps every "
                                  "whole record written before") from None
        finally:
            os.close(fd)


def _cut_back(fd: int, length: int) -> None:
    """Truncate the file to `length` bytes (its last whole line), so no torn record remains."""
    try:
        os.ftruncate(fd, length)
        os.fsync(fd)
    except OSError:
        pass  # the torn tail is then dropped by the next read (`read_records`) and resume


def read_records(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Every complete record in `path`, in file order; a torn last line is skipped.

    Raises a one-line ConfigError for a file that is not avsim's, or a corrupt line in it.
    """
    path = Path(path)
    if not path.exists():
        return []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise _foreign(path, "it is not text") from None
    except OSError as exc:
        raise ConfigError(f"cannot read {path} ({exc.strerror}); choose another --out") from None
    records = []
    for number, line in enumerate(text.splitlines(keepends=True), 1):
        if not line.endswith("\n"):
            break  # torn by a crash mid-write: that run did not finish
        problem, record = None, None
        try:
            record = json.loads(line)
        except ValueError as exc:
            problem = f"not JSON ({exc.msg})"
        else:
            problem = _record_problem(record)
        if problem is not None:
            looks_ours = isinstance(record, dict) and all(key in record for key in RECORD_KEYS)
            if number == 1 and not looks_ours:
                raise _foreign(path, f"its first line is {problem}")
            raise ConfigError(f"{path} line {number} is corrupt ({problem}); delete that line to resume "
                              f"(its run is run again), or choose another --out")
        records.append(_with_current_outcome(record))
    return records


def _record_problem(record: Any) -> str | None:
    """Why `record` is not a run record; None when it is one."""
    if not isinstance(record, dict):
        return f"a JSON {type(record).__name__}, not a run record"
    missing = [key for key in RECORD_KEYS if key not in record]
    if missing:
        return f"a JSON object without the run record key '{missing[0]}'"
    if record["status"] not in STATUSES:
        return f"a record with status {record['status']!r}, not one of {', '.join(STATUSES)}"
    result = record.get("result")
    if record["status"] == "ok" and not (isinstance(result, dict) and result.get("outcome") in (*ALL_OUTCOMES, *LEGACY_OUTCOMES)):
        return "an ok record without a known outcome"
    if record["status"] == "ok" and result["outcome"] in LEGACY_OUTCOMES and not all(
            key in result for key in ("margin_m", "sign_margin_m", "dist_at_brake_m")):
        return "an ok record whose result lacks its distances"
    return record_field_problem(record)


def _foreign(path: Path, why: str) -> ConfigError:
    # Read as an input (--config, --resume) or appended to as an output (--out): the fix names both.
    return ConfigError(f"{path} is not an avsim results file ({why}); to read runs, name a results.jsonl or runs.jsonl "
                       "that avsim wrote; to write them, choose another --out or move the file away")


def _with_current_outcome(record: dict[str, Any]) -> dict[str, Any]:
    """`record`, its result's outcome relabelled when it is one of LEGACY_OUTCOMES."""
    result = record.get("result")
    if not isinstance(result, dict) or result.get("outcome") not in LEGACY_OUTCOMES:
        return record
    outcome = classify_outcome(stopped=result["outcome"] != "did_not_stop", braked=result["dist_at_brake_m"] is not None,
                               line_dist_m=result["margin_m"], sign_dist_m=result["sign_margin_m"])
    return {**record, "result": {**result, "outcome": outcome}}


def rewrite(path: str | os.PathLike, records: Iterable[dict[str, Any]]) -> None:
    """Replace `path` with `records`, atomically (a temporary file renamed over it)."""
    write_text_atomic(path, "".join(encode(r) for r in records))
