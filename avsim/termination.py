"""SIGTERM and SIGHUP handled as Ctrl-C is.

A scheduler, `timeout` or `docker stop` ends a command with SIGTERM, and a closed terminal
with SIGHUP; by default either kills Python at once, leaving temporary files and no message.
`handle_termination` (installed by the command-line error boundary, `avsim.boundary`) turns
them into `Terminated`, a KeyboardInterrupt, so every path that already handles Ctrl-C
(temporaries removed, finished runs kept, workers stopped, a resume hint) handles them too.
The boundary then exits with 128 + the signal's number (143 for SIGTERM), as a shell reports
a command a signal stopped.

The Python API (a Gymnasium env, a notebook) installs nothing: a library does not take over
its caller's signals.
"""

from __future__ import annotations

import ctypes
import signal
import threading

# The signals handled as Ctrl-C. SIGHUP does not exist on every platform.
TERMINATION_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))

_received: int | None = None


class Terminated(KeyboardInterrupt):
    """A termination signal arrived; `signum` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def raise_if_interrupted(exc: BaseException) -> None:
    """Re-raise the Ctrl-C or termination signal that `exc` stands for; do nothing otherwise.

    A signal that lands inside a C call can come back as another exception: ctypes (under
    PyOpenGL's EGL calls) reports a KeyboardInterrupt raised while it converted an argument as
    an `ArgumentError` that only names it, and a library may chain one. A broad `except
    Exception` that turns errors into a user's error or a failed run calls this first, so the
    command stops as a Ctrl-C does (exit 130, 143 or 129) instead of blaming the environment.
    """
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            raise seen
        seen = seen.__cause__ or seen.__context__
    if isinstance(exc, ctypes.ArgumentError):
        if f": {Terminated.__name__}: " in str(exc) and _received is not None:
            raise Terminated(_received) from None
        if ": KeyboardInterrupt" in str(exc):
            raise KeyboardInterrupt from None


def _on_signal(signum: int, frame) -> None:
    global _received
    _received = signum
    # A second signal while the first is being handled would cut the clean-up short; the
    # first one has already decided how the command ends.
    for sig in TERMINATION_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated(signum)


def handle_termination() -> None:
    """Raise `Terminated` in the main thread on SIGTERM or SIGHUP (from the main thread only;
    elsewhere Python cannot install handlers, and nothing is done)."""
    global _received
    if threading.current_thread() is not threading.main_thread():
        return
    _received = None
    for sig in TERMINATION_SIGNALS:
        signal.signal(sig, _on_signal)


def received_signal() -> int | None:
    """The termination signal that arrived since `handle_termination`, or None (Ctrl-C, or nothing)."""
    return _received


def interrupt_exit_status() -> int:
    """128 + the signal that stopped the command: 143 for SIGTERM, 129 for SIGHUP, 130 for Ctrl-C."""
    return 128 + (_received if _received is not None else signal.SIGINT)


def interrupt_word() -> str:
    """How the boundary names the stop: "interrupted" (Ctrl-C) or "terminated (SIGTERM)"."""
    return "interrupted" if _received is None else f"terminated ({signal.Signals(_received).name})"
