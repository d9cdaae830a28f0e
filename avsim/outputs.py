"""Output files: checked before any work starts, written to temporary names, never claimed unwritten.

Every command declares its output arguments with `add_output_argument`, and the files it reads
with `add_input_argument`; `avsim.cli.main` checks them all with `check_declared_outputs` before
the command runs, so a path that cannot be written, or would replace a file the command reads,
is one line and exit 2 before the simulator is built:

    add_output_argument(run, "--json", kind=FILE, help="write the result record to this JSON file")
    add_output_argument(snap, "--out", kind=PREFIX, suffixes=("_front.png", "_side.png"), default="snapshot")
    add_input_argument(run, "--config", help="experiment file")   # --json onto it is refused

What "can be written" means, for every command alike:
- the name is not empty;
- a file is not an existing folder, nor an existing device or pipe (an atomic rename would
  replace /dev/null with a regular file);
- a folder is not an existing file;
- missing parent folders are created when the output is written, so the nearest existing
  ancestor must be a folder in which a file can really be created. That is tried, with a
  probe file removed at once: permission bits say nothing for root, and /proc or /sys
  refuse writes that `os.access` allows.

Files are written under a temporary name beside the output (`temporary_path`) and renamed
over it when complete. The name carries the writing process's id and host, so the next write
of the same output removes the temporaries of processes that are gone (a SIGKILLed run), and
never those of a live writer: `.NAME.PID@HOST.RANDOM.tmp[SUFFIX]`.
"""

from __future__ import annotations

import argparse
import os
import re
import secrets
import socket
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.errors import OutputError
from avsim.file_kinds import special_file_kind

FILE, FOLDER, PREFIX = "file", "folder", "prefix"
KINDS = (FILE, FOLDER, PREFIX)
# argparse defaults holding a subcommand's OutputArgs, and its inputs' (dest, flag) pairs.
_DEFAULT_KEY = "output_args"
_INPUTS_KEY = "input_args"


@dataclass(frozen=True)
class OutputArg:
    """One declared output of a command.

    dest: the argparse destination; flag: as the user types it (for messages);
    kind: FILE, FOLDER or PREFIX (files PREFIX + each of `suffixes`);
    suffix: a FILE's required ending (".mp4"); companions: suffixes of files written beside a
    FILE (`attack generate --out x.png` writes x.json too).
    """

    dest: str
    flag: str
    kind: str
    suffix: str | None = None
    suffixes: tuple[str, ...] = ()
    companions: tuple[str, ...] = ()


def add_output_argument(parser: argparse.ArgumentParser, flag: str, *, kind: str, suffix: str | None = None,
                        suffixes: Sequence[str] = (), companions: Sequence[str] = (), **kwargs: Any) -> argparse.Action:
    """`parser.add_argument(flag, **kwargs)`, declared as an output that `check_declared_outputs` checks."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    if kind == PREFIX and not suffixes:
        raise ValueError("a PREFIX output needs the suffixes of the files it names")
    action = parser.add_argument(flag, **kwargs)
    declared = parser.get_default(_DEFAULT_KEY) or ()
    spec = OutputArg(action.dest, flag, kind, suffix, tuple(suffixes), tuple(companions))
    parser.set_defaults(**{_DEFAULT_KEY: (*declared, spec)})
    return action


def add_input_argument(parser: argparse.ArgumentParser, flag: str, **kwargs: Any) -> argparse.Action:
    """`parser.add_argument(flag, **kwargs)`, declared as a file or folder the command reads (a
    value, or a list with nargs), so that `check_declared_outputs` refuses an output onto it."""
    action = parser.add_argument(flag, **kwargs)
    parser.set_defaults(**{_INPUTS_KEY: (*(parser.get_default(_INPUTS_KEY) or ()), (action.dest, flag))})
    return action


def declared_outputs(parser: argparse.ArgumentParser) -> tuple[OutputArg, ...]:
    """The output arguments `add_output_argument` declared on `parser` (none: an empty tuple)."""
    return parser.get_default(_DEFAULT_KEY) or ()


def check_declared_outputs(args: argparse.Namespace) -> None:
    """Check every output the parsed command declared (None: not asked for); raises OutputError,
    also when two outputs name one path (one would silently replace the other) or an output names
    an existing file or folder the command reads (it would replace its own input)."""
    claimed: dict[Path, str] = {}  # resolved path -> the flag that writes it
    for spec in getattr(args, _DEFAULT_KEY, ()):
        value = getattr(args, spec.dest, None)
        if value is None:
            continue
        if spec.kind == FILE:
            paths = [check_output_file(value, spec.flag, suffix=spec.suffix)]
            for companion in spec.companions:
                paths.append(check_output_file(str(Path(value).with_suffix(companion)), spec.flag))
        elif spec.kind == FOLDER:
            paths = [check_output_folder(value, spec.flag)]
        else:
            paths = check_output_prefix(value, spec.flag, spec.suffixes)
        for path in paths:
            key = path.resolve()
            if key in claimed and claimed[key] != spec.flag:
                raise OutputError(f"{claimed[key]} and {spec.flag} both write {path}; give each output its own path")
            claimed[key] = spec.flag
    for dest, flag in getattr(args, _INPUTS_KEY, ()):
        values = getattr(args, dest, None)
        for value in values if isinstance(values, list) else [values]:
            # Only a path that exists: an input may also be a name (--sign clean), not a file.
            if value and (kind := special_file_kind(value)):
                # /dev/zero would be read until memory runs out, a pipe with no writer blocks.
                reader = flag if flag.startswith("-") else f"the {flag} argument"
                raise OutputError(f"{value} ({reader}) is {kind}, not a regular file; give a file")
            if value and Path(value).exists() and Path(value).resolve() in claimed:
                reader = flag if flag.startswith("-") else f"the {flag} argument"
                raise OutputError(f"{claimed[Path(value).resolve()]} would replace {value}, which {reader} reads; "
                                  "give the output its own path")


def check_output_file(path: str | os.PathLike, flag: str, *, suffix: str | None = None) -> Path:
    """Raise OutputError unless `path` names a file that can be written (see the module docstring)."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f"{flag} needs a file name, got '{text}'")
    p = Path(text)
    if text.endswith(os.sep) or p.name in ("", ".", ".."):
        raise OutputError(f"{flag} '{text}' names a folder; give a file name" + (f", e.g. {p / ('out' + suffix)}" if suffix else ""))
    if suffix is not None and p.suffix.lower() != suffix:
        raise OutputError(f"{flag} expects a path ending in {suffix}, got '{text}'")
    if p.is_dir():
        ending = suffix or p.suffix
        raise OutputError(f"{flag} '{text}' is a folder; give a file name inside it" + (f", e.g. {p / ('out' + ending)}" if ending else ""))
    if kind := special_file_kind(p):
        raise OutputError(f"{flag} '{text}' is {kind}, not a regular file; give another path")
    if p.is_symlink():  # the file is written beside and renamed into place, which replaces the link, not its target
        raise OutputError(f"{flag} '{text}' is a symbolic link (to {os.readlink(p)}); give the path it points to, or "
                          "another path")
    _check_can_create_in(p.parent, flag, text)
    return p


def check_output_folder(path: str | os.PathLike, flag: str) -> Path:
    """Raise OutputError unless `path` is a folder, or can be made one, in which files can be written."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f"{flag} needs a folder name, got '{text}'")
    p = Path(text)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{flag} '{text}' is a file, not a folder; give a folder path")
    _check_can_create_in(p, flag, text)
    return p


def refuse_earlier_outputs(folder: Path, names: Sequence[str], flag: str = "--out") -> None:
    """A one-line OutputError when `folder` already holds any of the files `names` that a command writes into it
    only after its work (an earlier run's results, or a file of the user's), which the command would replace."""
    held = [name for name in names if (folder / name).exists()]
    if held:
        raise OutputError(f"{flag} {folder} already holds {', '.join(held)}, which this run would replace; choose "
                          f"another {flag}, or remove them to run it again")


def check_output_prefix(prefix: str, flag: str, suffixes: Sequence[str]) -> list[Path]:
    """Check each file `prefix + suffix`; a prefix must name files, not only a folder."""
    if not prefix.strip() or prefix.endswith(os.sep) or Path(prefix).name in ("", ".", ".."):
        raise OutputError(f"{flag} needs a file name prefix such as shots/town03 (writes shots/town03{suffixes[0]}), got '{prefix}'")
    return [check_output_file(prefix + suffix, flag) for suffix in suffixes]


def _check_can_create_in(folder: Path, flag: str, text: str) -> None:
    """The nearest existing ancestor of `folder` must be a folder where a file can be created."""
    existing = folder if str(folder) else Path(".")
    while not existing.exists():
        if existing.is_symlink():
            raise OutputError(f"{flag} '{text}': {existing} is a broken link; give another path")
        existing = existing.parent
    if not existing.is_dir():
        raise OutputError(f"{flag} '{text}': {existing} is a file, so no folder can be made there; give another path")
    try:
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".avsim-write-test-")
    except OSError as exc:
        raise OutputError(f"{flag} '{text}': cannot write in {existing} ({exc.strerror}); give a writable path") from None
    os.close(fd)
    os.unlink(probe)


# ---- temporary files -----------------------------------------------------------------------

_HOST = re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname()) or "host"
# Every temporary name this process handed out that may still exist (a renamed one no longer
# does), so a worker told to stop can delete its own before it exits: `remove_own_temporaries`.
_OWN_TEMPORARIES: set[Path] = set()


def temporary_path(path: str | os.PathLike, suffix: str = "") -> Path:
    """A fresh temporary name beside `path` (same file system, so a rename is atomic), after
    removing the temporaries of `path` left by writers that are gone.

    suffix: appended after ".tmp" (OpenCV picks a video container from the extension).
    """
    path = Path(path)
    remove_stale_temporaries(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}@{_HOST}.{secrets.token_hex(6)}.tmp{suffix}")
    _OWN_TEMPORARIES.add(tmp)
    return tmp


def remove_own_temporaries() -> None:
    """Delete every temporary file this process is still writing: for a process about to exit
    without unwinding (a terminated or orphaned worker), so it leaves no half-written file."""
    for tmp in list(_OWN_TEMPORARIES):
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        _OWN_TEMPORARIES.discard(tmp)


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Delete `path`'s temporaries whose writer (a process on this host) no longer exists; returns them."""
    path = Path(path)
    pattern = re.compile(rf"\.{re.escape(path.name)}\.(\d+)@([A-Za-z0-9-]+)\.[0-9a-f]+\.tmp.*")
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:  # no folder yet: nothing to clean
        return removed
    for sibling in siblings:
        match = pattern.fullmatch(sibling.name)
        if match is None or match.group(2) != _HOST or _alive(int(match.group(1))):
            continue
        try:
            sibling.unlink()
            removed.append(sibling)
        except FileNotFoundError:
            pass  # another writer cleaned it first
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


# ---- checked writes ------------------------------------------------------------------------

def write_image(path: str | os.PathLike, image_bgr: Any, params: Sequence[int] = (), *, atomic: bool = True) -> Path:
    """`cv2.imwrite` that raises OutputError naming the file when nothing was written.

    image_bgr: (H, W, 3) uint8 in OpenCV's BGR order; the format follows the suffix.
    atomic: encode, then write through a temporary file renamed over `path` (a reader never
    sees half an image); False writes in place, for files inside a folder that is itself
    renamed into place when complete. `cv2.imwrite` only returns False, so the bytes are
    written here, where an OSError can say why.
    """
    import cv2

    path = Path(path)
    try:
        ok, encoded = cv2.imencode(path.suffix, image_bgr, list(params))
    except cv2.error as exc:
        raise OutputError(f"cannot write {path}: OpenCV cannot encode a '{path.suffix}' image ({str(exc).strip().splitlines()[-1]})") from None
    if not ok:
        raise OutputError(f"cannot write {path}: OpenCV could not encode a '{path.suffix}' image")
    if atomic:
        write_bytes_atomic(path, encoded.tobytes())
    else:
        _write_bytes_in_place(path, encoded.tobytes())
    return path


def write_text(path: str | os.PathLike, text: str, *, atomic: bool = True) -> Path:
    """Write `text` (UTF-8) to `path`: through a temporary file renamed over it (`write_bytes_atomic`),
    or, with atomic False, in place, for files inside a folder that is itself renamed into place
    when complete. A failed write is an OutputError naming the file."""
    path = Path(path)
    if atomic:
        write_bytes_atomic(path, text.encode())
    else:
        _write_bytes_in_place(path, text.encode())
    return path


def _write_bytes_in_place(path: Path, data: bytes) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    except OSError as exc:
        raise OutputError(f"cannot write {path} ({exc.strerror or exc})") from None


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write `data` to a temporary file beside `path`, fsync it, and rename it over `path`;
    an OSError becomes an OutputError naming `path`."""
    write_reserved(reserve_temporary(path), path, data)


def reserve_temporary(path: str | os.PathLike) -> Path:
    """Create `path`'s folder and an empty temporary file beside it (`temporary_path`), for a writer
    that fills it later (`write_reserved`): an unwritable place fails now, before the work, and a
    writer killed meanwhile leaves a temporary that the next write of `path` removes.
    An OSError becomes an OutputError naming `path`."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: cannot create its folder ({exc.strerror or exc})") from None
    tmp = temporary_path(path)
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except OSError as exc:
        _OWN_TEMPORARIES.discard(tmp)
        raise OutputError(f"cannot write {path} ({exc.strerror or exc})") from None
    return tmp


def write_reserved(tmp: Path, path: str | os.PathLike, data: bytes) -> None:
    """Fill the temporary `tmp` from `reserve_temporary(path)` with `data`, fsync it and rename it
    over `path`. On any failure `tmp` is removed; an OSError (a full disk) becomes an OutputError
    naming `path`."""
    path = Path(path)
    try:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"cannot write {path} ({exc.strerror or exc})") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        _OWN_TEMPORARIES.discard(tmp)
