"""One command at a time per results folder.

Two sweeps started into one `--out` would both append to its results.jsonl and then each
rewrite it with its own runs, losing the other's. `locked_output` refuses the second in one
line, naming the process that holds the folder:

    with locked_output(out, "avsim sweep FILE --out DIR", results_name="results.jsonl"):
        ...                                          # read, run, write into `out`

The lock is `OUT/.avsim.lock`, held with `fcntl.flock`, which the kernel releases when the
holder exits by any means (a SIGKILL, the OOM killer, a crash). A lock left by a killed process
is therefore stale by construction and the next command simply takes it over: there is no
pid to guess about, and no race between two processes that both find a stale lock. The file
holds the holder's pid, host and command, for the refusal's message only.

A folder this command made is removed again when the command fails before any run was
recorded in `results_name` (a Ray cluster that cannot be reached, a bad resume), so a failed
start leaves no empty results folder behind.

A command names the files and folders it will write into the folder (`files`, `folders`), and
they are checked once the lock is held, before the block runs: a summary.md that is a folder, or
an OUT/rrd that is a file, would otherwise be found after hours of runs, when the report or the
first recording is written.

A command that builds its output elsewhere and renames it into place (`avsim detector
make-data`) holds `locked_sibling(out, ...)` instead: the lock file `.<name>.avsim.lock` sits
beside `out`, which may not exist yet and is replaced whole.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import socket
from collections.abc import Iterable, Iterator
from pathlib import Path

from avsim.errors import OutputError
from avsim.file_kinds import special_file_kind

LOCK_NAME = ".avsim.lock"


@contextlib.contextmanager
def locked_output(folder: str | os.PathLike, command: str, *, results_name: str | None = None,
                  files: Iterable[str] = (), folders: Iterable[str] = ()) -> Iterator[Path]:
    """Hold `folder` (made if missing) for the duration of the block; yields it.

    Raises OutputError in one line when another live process holds it. results_name: the
    file whose records make the folder worth keeping when the block fails (see the module docstring).
    files, folders: paths relative to `folder` that the block will write (`check_writable`), checked
    before it runs.
    """
    folder = Path(folder)
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot make the results folder {folder} ({exc.strerror or exc})") from None
    try:
        fd = _acquire(folder / LOCK_NAME, command, folder)
    except BaseException:
        if created:  # only if still empty: a second command racing to make it may hold it now
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    try:
        check_writable(folder, files, folders)
        yield folder
    except BaseException:
        _remove_if_unused(folder, created, results_name)  # still holding the lock: no one else writes here
        raise
    finally:
        _release(folder / LOCK_NAME, fd)


@contextlib.contextmanager
def locked_sibling(output: str | os.PathLike, command: str) -> Iterator[Path]:
    """Hold `output` (a file or folder, made or replaced by the block) for the block's duration
    through a lock file beside it; yields `output`. OutputError in one line when another live
    process holds it."""
    output = Path(output)
    lock = output.with_name(f".{output.name}{LOCK_NAME}")
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot make the folder {output.parent} ({exc.strerror or exc})") from None
    fd = _acquire(lock, command, output)
    try:
        yield output
    finally:
        _release(lock, fd)


def check_writable(folder: Path, files: Iterable[str] = (), folders: Iterable[str] = ()) -> None:
    """A one-line OutputError when one of `files` (paths relative to `folder`) cannot be written as a
    file, or one of `folders` made as a folder: something of the other kind, or a device or pipe, is
    in its place or in the place of a folder above it. What is missing passes: it will be made."""
    for name, want_folder in [*((name, False) for name in files), *((name, True) for name in folders)]:
        path = folder
        parts = Path(name).parts
        for depth, part in enumerate(parts, 1):
            path = path / part
            is_folder = want_folder or depth < len(parts)
            if not path.exists():
                break  # made when it is written, with any folder below it
            special = special_file_kind(path)
            if is_folder and not path.is_dir():
                raise OutputError(f"{path} is {special or 'a file'}, where this command makes a folder; remove or "
                                  "rename it, or choose another --out")
            if not is_folder and path.is_dir():
                raise OutputError(f"{path} is a folder, where this command writes a file; remove or rename it, "
                                  "or choose another --out")
            if not is_folder and special:  # worded as check_output_file's refusal of the same
                raise OutputError(f"{path} is {special}, not a regular file, where this command writes a file; "
                                  "remove it, or choose another --out")


def _acquire(path: Path, command: str, held: Path) -> int:
    """An open, flock-ed descriptor of the lock file `path`, which then names this process; held:
    the output it guards, for the refusal's message."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:  # a folder of that name, or no right to make the file
            raise OutputError(f"cannot lock {held}: cannot open its lock file {path} ({exc.strerror or exc}); "
                              "remove what is there, or choose another --out") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _read_holder(fd)
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise OutputError(f"cannot lock {held} ({exc.strerror or exc})") from None
            raise OutputError(f"{held} is in use by {holder or 'another avsim command'}; wait for it to finish, "
                              f"or choose another --out") from None
        # The previous holder may have unlinked the file between our open and our lock: then we
        # hold a lock on a file no one else can see, and must take the one at `path`.
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.write(fd, f"pid {os.getpid()} on {socket.gethostname()} ({command})\n".encode())
    return fd


def _read_holder(fd: int) -> str:
    try:
        return os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""


def _release(path: Path, fd: int) -> None:
    # Unlinked while still held, so no other process can lock this file after we let it go.
    with contextlib.suppress(OSError):
        path.unlink()
    os.close(fd)


def _remove_if_unused(folder: Path, created: bool, results_name: str | None) -> None:
    """Remove `folder` when this command made it and recorded no run in it."""
    if not created:
        return
    results = folder / results_name if results_name else None
    if results is not None and results.exists() and results.stat().st_size > 0:
        return
    shutil.rmtree(folder, ignore_errors=True)
