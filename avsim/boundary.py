"""The command-line error boundary, shared by `avsim` and every `python -m avsim....` entry point.

    raise SystemExit(run_guarded(lambda: main(argv), prog="python -m avsim.vehicle.brake_test"))

`run_guarded` installs SIGTERM/SIGHUP handling (`avsim.termination`) and runs the command.
What the user sees when something stops it, always one line on stderr:
- an AvsimError (bad input, a bad environment): "PROG: error: ...", exit 2 (a PhysicsError 3,
  every run of a batch failed 1);
- Ctrl-C, SIGTERM or SIGHUP: "PROG: interrupted; ..." (or "terminated (SIGTERM)"), saying what
  was kept and how to resume, exit 128 + the signal (130, 143, 129);
- an OSError (a full disk, say): "PROG: error: ...", naming the file, exit 1;
- anything else, a bug: "PROG: internal error: ...", with the path of a file holding the full
  traceback, exit 1.
With `debug` the full traceback is printed as well. Python warnings raised meanwhile are printed
after a command that succeeded, one line each, and dropped beside a refusal.
"""

from __future__ import annotations

import os
import sys
import tempfile
import traceback
import warnings
from collections.abc import Callable

from avsim.errors import AvsimError, Interrupted
from avsim.termination import handle_termination, interrupt_exit_status, interrupt_word, raise_if_interrupted


def run_guarded(body: Callable[[], int | None], *, prog: str = "avsim", debug: bool = False) -> int:
    """Run `body` (returns an exit status, or None for 0) inside the boundary; its exit status."""
    handle_termination()
    with warnings.catch_warnings(record=True) as caught:
        status = _run(body, prog, debug)
    # Python warnings (a library's deprecation, torch's note on an old pickle) come after the
    # outcome, one line each, and not at all beside a refusal, whose one line says what matters.
    if status == 0:
        for warning in caught:
            print(one_line(f"{prog}: warning: {warning.message}"), file=sys.stderr)
    return status


def _run(body: Callable[[], int | None], prog: str, debug: bool) -> int:
    try:
        return body() or 0
    except Interrupted as exc:
        return _report(f"{prog}: {interrupt_word()}; {exc}", interrupt_exit_status(), debug)
    except AvsimError as exc:
        return _report(f"{prog}: error: {exc}", exc.exit_code, debug)
    except KeyboardInterrupt:
        return _interrupted(prog, debug)
    except OSError as exc:  # the machine's: a full disk, a folder removed under a running command
        where = _save_traceback()
        return _report(f"{prog}: error: {exc.strerror or exc}" + (f": '{exc.filename}'" if exc.filename else "")
                       + f" (full traceback in {where}, or rerun with --debug)", 1, debug)
    except Exception as exc:  # noqa: BLE001 - the one place that turns a bug into one line and a file
        try:
            raise_if_interrupted(exc)  # a Ctrl-C that a C call wrapped in another exception
        except KeyboardInterrupt:
            return _interrupted(prog, debug)
        where = _save_traceback()
        return _report(f"{prog}: internal error: {type(exc).__name__}: {one_line(str(exc))} (a bug in avsim; "
                       f"full traceback in {where}, or rerun with --debug)", 1, debug)


def _interrupted(prog: str, debug: bool) -> int:
    return _report(f"{prog}: {interrupt_word()}; every file is written whole or not at all, so none is half-written",
                   interrupt_exit_status(), debug)


def _report(message: str, status: int, debug: bool) -> int:
    if debug:
        traceback.print_exc()
    print(one_line(message), file=sys.stderr)
    return status


def one_line(text: str) -> str:
    """`text` with its lines joined by single spaces, blank lines dropped: an error message on one line."""
    return " ".join(line.strip() for line in text.splitlines() if line.strip())


def _save_traceback() -> str:
    """Write the exception being handled, with its traceback, to a new file in the temp folder; its path."""
    try:
        fd, path = tempfile.mkstemp(prefix="avsim-traceback-", suffix=".txt")
        with os.fdopen(fd, "w") as handle:
            handle.write(f"{' '.join(sys.argv)}\n\n{traceback.format_exc()}")
        return path
    except OSError:
        return "nowhere (the temp folder is not writable)"
