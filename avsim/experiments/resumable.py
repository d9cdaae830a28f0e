"""A batch of runs into one folder's `results.jsonl` that survives crashes and resumes: what
`avsim sweep` and `avsim leaderboard` share.

    existing = existing_records(out / RESULTS_FILE, resume)    # first: refuses before anything is written
    ...                                                         # the caller's own files (its input, a manifest)
    records, ran = run_resumable(specs, out / RESULTS_FILE, existing, resume_command="avsim sweep ... --resume",
                                 workers=2, description="sweep")

Each finished run is one fsynced line (`avsim.experiments.results_file`). With `resume`, runs
whose config hash already has an `ok` record are not run again; failed ones are. Once the
batch is over the file is rewritten in the order of `specs`, the same every time, with the
records of runs no longer asked for kept after them. A file killed at any moment, even
mid-write (a torn last line is dropped before new records are appended), resumes to the same
file as a batch never stopped, `wall_s` aside. Ctrl-C ends the batch with `Interrupted`, naming
the finished runs and the command that resumes it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from avsim.errors import ConfigError, Interrupted, OutputError
from avsim.workers import DEFAULT_BATCH
from avsim.experiments.batch import run_batch
from avsim.experiments.plan import count_of
from avsim.experiments.results_file import JsonlWriter, read_records, rewrite
from avsim.experiments.run_task import RunSpec

RESULTS_FILE = "results.jsonl"
Record = dict[str, Any]


def kept_value(folder: Path, file_name: str, key: str, kind: type, absent: Any, what: str, fix: str) -> Any:
    """`key`'s value in the JSON file `file_name` that a command keeps in FOLDER beside its runs (`absent` where there
    is no such file); a one-line ConfigError, for a `--resume` of FOLDER, where the file is not one avsim wrote.
    what: the value in words ("a table of keys"); fix: the message's way out."""
    path = folder / file_name
    if not path.is_file():
        return absent
    try:
        held = json.loads(path.read_text())[key]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"--resume {folder}: its {file_name} cannot be read ({exc}); it is not one avsim wrote: "
                          f"{fix}") from None
    if not isinstance(held, kind):
        raise ConfigError(f"--resume {folder}: its {file_name} is not one avsim wrote (no {what} under '{key}'); {fix}")
    return held


def holds_runs(results_path: Path) -> bool:
    """Whether `results_path` exists and is not empty: a folder whose runs a resume would add to (its --setting and
    --set values matter), not one a first command makes."""
    return results_path.is_file() and results_path.stat().st_size > 0


def existing_records(results_path: Path, resume: bool) -> list[Record]:
    """The records already in `results_path`; a one-line ConfigError when there are some and
    `resume` is off, or the file is not avsim's or has a corrupt line (`read_records`)."""
    existing = read_records(results_path)
    if existing and not resume:
        raise ConfigError(f"{results_path} already holds {len(existing)} runs; pass --resume to run only the "
                          f"missing ones, or choose another --out")
    return existing


def run_resumable(specs: Iterable[RunSpec], results_path: Path, existing: Sequence[Record], *, resume_command: str,
                  workers: int | None, progress: bool = True, description: str = "runs", backend: str = "local",
                  address: str | None = None, decorate: Callable[[Record], Record] | None = None,
                  batch: int = DEFAULT_BATCH, total: int | None = None,
                  by_run: bool = False) -> tuple[list[Record], int]:
    """Run the specs that `existing` has no ok record of; returns (one record per spec, in spec
    order; how many were run). The specs' config hashes must differ, unless `by_run`.

    by_run: match records to specs by (experiment, cell, seed, config hash) rather than by the
    config hash alone, so that one config may appear under several names (two experiment files
    of `avsim reproduce` that share a cell); those names must then differ.

    specs: a list or a `Plan`, built as the batch draws on it: a finished run is skipped as its
    spec comes, and only the specs' hashes (their order) are kept, not the specs.
    total: how many specs there are (default: a plan's size, a list's length), for the progress bar.
    decorate: applied to each new record before it is written (e.g. to add a sweep's grid point).
    The other options go to `avsim.experiments.batch.run_batch`; the batch folder is
    `results_path`'s.
    """
    key_of_record = record_key if by_run else (lambda record: record.get("spec_hash"))
    key_of_spec = spec_key if by_run else (lambda spec: spec.spec_hash)
    finished = {key_of_record(r): r for r in existing if r.get("status") == "ok"}
    if total is None:
        total = count_of(specs)
    order: dict[Hashable, None] = {}  # the specs' keys in spec order, as they are built

    def todo() -> Iterator[RunSpec]:
        for spec in specs:
            key = key_of_spec(spec)
            if key in order:
                raise ValueError("two specs share a run key; run each config (each named run, with by_run) once")
            order[key] = None
            if key not in finished:
                yield spec

    # `run_batch` draws on `todo` until it runs out, so once it returns `order` holds every spec's hash.
    results_path.parent.mkdir(parents=True, exist_ok=True)
    if _torn_tail(results_path):
        rewrite(results_path, existing)  # else the next record would be glued onto the torn line
    writer = JsonlWriter(results_path)
    ran: dict[Hashable, Record] = {}

    def on_record(record: Record) -> None:
        if decorate is not None:
            record = decorate(record)
        # Counted first, so a Ctrl-C that lands after the line is written never reports it missing;
        # a line that could not be written (a full disk) is not counted.
        key = key_of_record(record)
        ran[key] = record
        try:
            writer.append(record)
        except OutputError:
            del ran[key]
            raise

    # The bar counts the runs to run: every spec but the finished ones (an estimate where the file
    # holds runs no longer asked for; `run_batch` corrects it once the specs run out).
    to_run = None if total is None else max(0, total - len(finished))
    try:
        run_batch(todo(), workers=workers, root=results_path.parent, on_record=on_record, progress=progress,
                  description=description, backend=backend, address=address, batch=batch, total=to_run)
    except KeyboardInterrupt:
        raise Interrupted(resume_hint(resume_command, results_path, len(finished) + len(ran))) from None
    except OutputError as exc:  # a full disk: the file holds whole records only, so a resume loses none
        raise OutputError(f"{exc}; {resume_hint(resume_command, results_path, len(finished) + len(ran))}") from None
    records = [ran.get(key) or finished[key] for key in order]
    others = [r for r in existing if key_of_record(r) not in order]
    rewrite(results_path, records + others)
    return records, len(ran)


def manifest_history(manifest_path: Path) -> list[Record]:
    """The earlier invocations that filled a resumed folder, from its manifest.json (resumed ones
    included): command, start, wall time, runs run; [] when there is no readable manifest."""
    try:
        previous = json.loads(manifest_path.read_text())
    except (OSError, ValueError):
        return []
    earlier = previous.get("history", [])
    return [*earlier, {k: previous[k] for k in ("command", "started_at", "wall_s", "ran") if k in previous}]


def spec_key(spec: RunSpec) -> tuple[str, str, int, str]:
    """A run's identity under `by_run`: where it is in its batch, and what it runs."""
    return spec.experiment, spec.cell, spec.seed, spec.spec_hash


def record_key(record: Record) -> tuple[Any, Any, Any, Any]:
    """The `spec_key` of the run a record is of."""
    return record.get("experiment"), record.get("cell"), record.get("seed"), record.get("spec_hash")


def resume_hint(command: str, results_path: Path, finished: int) -> str:
    """What an interrupted batch kept, and the command that finishes it."""
    if not finished:
        return f"no run had finished; run it again with: {command}"
    return f"{finished} finished run{'s are' if finished != 1 else ' is'} in {results_path}; resume with: {command}"


def _torn_tail(path: Path) -> bool:
    """True when `path` ends in a line without its newline: a write cut short by a crash."""
    try:
        with path.open("rb") as f:
            f.seek(-1, os.SEEK_END)
            return f.read(1) != b"\n"
    except OSError:  # no file, or an empty one
        return False
