"""Which kind of special file a path is: the one test behind every "not a regular file" refusal.

A path that is neither a regular file nor a folder is refused wherever avsim reads or writes a
user's file: a device would be read until memory runs out (/dev/zero), a pipe with no writer
blocks its reader for ever, and an output renamed into place would replace /dev/null. Each
caller keeps its own error type and fix; this module only says what was found, so that every
refusal names it the same way: "... is a pipe (FIFO), not a regular file; ...".
"""

from __future__ import annotations

import os
import stat

# The phrase for each special kind, tried in order on the mode of os.stat.
_KINDS = ((stat.S_ISCHR, "a device"), (stat.S_ISBLK, "a device"), (stat.S_ISFIFO, "a pipe (FIFO)"),
          (stat.S_ISSOCK, "a socket"))


def special_file_kind(path: str | os.PathLike) -> str | None:
    """"a device", "a pipe (FIFO)" or "a socket" when `path` is one, after following symbolic links
    as `Path.is_file` does; None for a regular file, a folder, or a path that does not exist or
    cannot be looked at (the caller's own open then says why).

    Any other kind that is neither a regular file nor a folder is "a special file", so a caller
    refuses exactly what `exists() and not (is_file() or is_dir())` refused.
    """
    try:
        # fspath first: os.stat would take an int as a file descriptor and describe stdout.
        mode = os.stat(os.fspath(path)).st_mode
    except (OSError, ValueError):  # ValueError: a NUL byte in the name, which Path.exists reads as missing
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((phrase for is_kind, phrase in _KINDS if is_kind(mode)), "a special file")
