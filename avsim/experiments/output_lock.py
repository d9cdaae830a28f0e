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
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import shutil
import socket
from collections.abc import Iterator
from pathlib import Path

from avsim.errors import OutputError

LOCK_NAME = ".avsim.lock"


@contextlib.contextmanager
def locked_output(folder: str | os.PathLike, command: str, *, results_name: str | None = None) -> Iterator[Path]:
    """Hold `folder` (made if missing) for the duration of the block; yields it.

    Raises OutputError in one line when another live process holds it. results_name: the
    file whose records make the folder worth keeping when the block fails (see the module docstring).
    """
    folder = Path(folder)
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot make the results folder {folder} ({exc.strerror or exc})") from None
    try:
        fd = _acquire(folder / LOCK_NAME, command)
    except BaseException:
        if created:  # only if still empty: a second command racing to make it may hold it now
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    try:
        yield folder
    except BaseException:
        _remove_if_unused(folder, created, results_name)  # still holding the lock: no one else writes here
        raise
    finally:
        _release(folder / LOCK_NAME, fd)


def _acquire(path: Path, command: str) -> int:
    """An open, flock-ed descriptor of `path`, which then names this process."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _read_holder(fd)
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise OutputError(f"cannot lock {path.parent} ({exc.strerror or exc})") from None
            raise OutputError(f"{path.parent} is in use by {holder or 'another avsim command'}; wait for it to finish, "
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
