"""JSON-lines results files that survive crashes: one record per line, each flushed to disk.

Each record is written as one `write` of a complete line, then flushed and fsynced, so a
crash can leave at most a torn *last* line; `read_records` skips such a line (it is a run
that never finished) and reads every complete one.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from avsim.metrics import write_text_atomic


def encode(record: dict[str, Any]) -> str:
    """One record as one line (no NaN: JSON has none)."""
    return json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n"


class JsonlWriter:
    """Appends records to `path`, one durable line each."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def append(self, record: dict[str, Any]) -> None:
        line = encode(record).encode()
        # O_APPEND: the line lands whole at the end even if another writer appended meanwhile.
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line)
            os.fsync(fd)
        finally:
            os.close(fd)


def read_records(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Every complete record in `path`, in file order; a torn last line is skipped."""
    path = Path(path)
    if not path.exists():
        return []
    records = []
    for line in path.read_text().splitlines(keepends=True):
        if not line.endswith("\n"):
            break  # torn by a crash mid-write: that run did not finish
        records.append(json.loads(line))
    return records


def rewrite(path: str | os.PathLike, records: Iterable[dict[str, Any]]) -> None:
    """Replace `path` with `records`, atomically (a temporary file renamed over it)."""
    write_text_atomic(path, "".join(encode(r) for r in records))
