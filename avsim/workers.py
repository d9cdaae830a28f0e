"""Worker processes that never outlive the process that started them.

A pool worker whose parent was SIGKILLed (by the OOM killer, say) is re-parented and would
go on running, and holding its memory, for as long as its queue feeds it. Every worker runs
`watch_parent` instead: a daemon thread that polls the parent's pid and ends the worker once
the parent is gone. Linux's PR_SET_PDEATHSIG would be quicker but fires when the *thread* that
forked the worker exits, which in a `ProcessPoolExecutor` is not the parent's death.

    pool = ProcessPoolExecutor(workers, mp_context=spawn, initializer=init_worker, initargs=(env, os.getpid()))
    ...
    terminate_workers(pool)          # Ctrl-C: stop the runs in flight now, not when they finish

Workers ignore SIGINT: Ctrl-C in a terminal reaches the whole process group, and the parent
alone decides what to keep and stops its workers (else each worker prints a traceback). A
worker that is stopped (SIGTERM, from `terminate_workers`) or orphaned deletes the temporary
files it was writing (`avsim.outputs.remove_own_temporaries`) and exits at once.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
import typing
from concurrent.futures import ProcessPoolExecutor

from avsim.outputs import remove_own_temporaries

# Runs a worker or Ray task steps in lock-step by default (`--batch`): batches of 8 share the bf16 network
# call best per core here (`avsim bench`), and a killed batch loses at most 8 runs in flight per worker.
DEFAULT_BATCH = 8
BATCH_HELP = (f"runs each worker or Ray task steps together, one network call per control tick over all their cars "
              f"(default {DEFAULT_BATCH}; 1: one at a time); results are the same at any size")

# How often a worker checks that its parent is alive [s]; a worker outlives it by at most this.
PARENT_POLL_S = 1.0
# Exit status of a worker that ended because its parent was gone (128 + SIGHUP, like a hang-up),
# and of one stopped by SIGTERM (128 + 15).
ORPHAN_EXIT_STATUS = 129
TERMINATED_EXIT_STATUS = 143

_watching: set[int] = set()
_watch_lock = threading.Lock()


# The filter, in `python -W` form, that keeps multiprocessing's resource tracker quiet about the
# semaphores a SIGKILLed parent could not release: the tracker releases them, and its two-line
# warning would follow whatever the killed command last printed.
_TRACKER_FILTER = "ignore:resource_tracker:UserWarning"


def quiet_resource_tracker() -> None:
    """Pass `_TRACKER_FILTER` to the resource tracker process, which takes this interpreter's -W
    options when a pool first starts it (call before the first pool)."""
    if _TRACKER_FILTER not in sys.warnoptions:
        sys.warnoptions.append(_TRACKER_FILTER)


def init_worker(env: dict[str, str], parent_pid: int) -> None:
    """A pool's initializer: `env` into the environment (before any GL context), SIGINT ignored,
    and the parent watched."""
    os.environ.update(env)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):  # a closed terminal hangs up the whole group; the parent decides, as for Ctrl-C
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    # Not an exception: the pool's worker loop would catch it and carry on with the next task.
    signal.signal(signal.SIGTERM, lambda signum, frame: exit_now(TERMINATED_EXIT_STATUS))
    watch_parent(parent_pid)


def exit_now(status: int) -> typing.NoReturn:
    """End this worker at once, without unwinding, after deleting the temporary files it was writing."""
    remove_own_temporaries()
    os._exit(status)


def watch_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> None:
    """End this process (os._exit) within `poll_s` of `parent_pid` ceasing to be its parent.

    Idempotent per parent: called again (by a worker that is initialised twice), it starts no second thread.
    """
    with _watch_lock:
        if parent_pid in _watching:
            return
        _watching.add(parent_pid)
    if os.getppid() != parent_pid:  # already gone before the thread could start
        exit_now(ORPHAN_EXIT_STATUS)

    def _watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        # The parent that would receive this worker's results is gone: nothing is worth finishing.
        exit_now(ORPHAN_EXIT_STATUS)

    threading.Thread(target=_watch, name="avsim-parent-watch", daemon=True).start()


def terminate_workers(pool: ProcessPoolExecutor) -> None:
    """Stop `pool` now: cancel what has not started and SIGTERM the workers still running a task.

    `ProcessPoolExecutor.shutdown` waits for the runs in flight, which can take minutes; Python
    3.14 has `terminate_workers()` for this, and before it the worker processes are only
    reachable through the executor's `_processes` table.
    """
    terminate = getattr(pool, "terminate_workers", None)
    if terminate is not None:
        terminate()
        return
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=5)
