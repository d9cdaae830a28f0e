"""Run many closed-loop configs in worker processes; each finished run is one JSON record.

    specs = [RunSpec("table3_stop_positions", run.cell_name, run.seed, run.config) for run in experiment.runs()]
    records = run_batch(specs, workers=2, on_record=writer.append)
    records = run_batch(specs, workers=2, backend="ray")     # the same runs as Ray tasks
    records = run_batch(plan, workers=2)                     # a Plan: specs built as the workers need them

Every run is `avsim.runner.run_recorded`, exactly what `avsim run` executes, so one record
can be re-run alone with `avsim run --config FILE --cell NAME --seed K`. A run that raises
becomes a `failed` record carrying the error, and the batch goes on.

Backends (`BACKENDS`); both run `run_task.execute_group(specs, root)` for each lock-step group:
    local   this process (workers 1) or a pool of `workers` `spawn`ed processes on this
            machine; each builds its own MuJoCo model and EGL context (an OpenGL context
            must never cross a fork). A worker process that dies stops the batch. The
            workers exit when this process dies, and a batch stopped early (Ctrl-C)
            stops them at once rather than waiting for their runs (`avsim.workers`).
    ray     Ray tasks on a cluster, or on a local one of `workers` CPUs
            (`avsim.experiments.ray_backend`, an optional extra: pip install 'avsim[ray]').
Records, `on_record` and the progress bar are one code path for both. Either draws lock-step
groups from the specs only as workers free up (`avsim.experiments.plan`), so a plan of any size
starts its first run at once and is never held whole.

Many cars per process (`batch`, either backend): each worker or Ray task steps up to `batch` runs in
lock-step (`avsim.lockstep`), one network call per control tick over all their cars' frames.
A run's record is the same, bit for bit, alone or in a batch of any size (`wall_s` aside: in a
batch it is the run's share of the batch's time).

A record is one line of `runs.jsonl`; its fields are `avsim.experiments.run_task`'s.
"""

from __future__ import annotations

import itertools
import multiprocessing
import os
from collections.abc import Callable, Collection, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from avsim.errors import ConfigError
from avsim.experiments.plan import Counted, Group, count_of, group_size, in_flight, lockstep_groups, specs_of
from avsim.experiments.ray_backend import check_reachable, ray_results, require_ray
from avsim.experiments.run_task import RunSpec, execute_group, worker_env
from avsim.sensors.gl import check_offscreen_rendering
from avsim.workers import DEFAULT_BATCH, init_worker, terminate_workers

BACKENDS = ("local", "ray")
# Lock-step groups handed to a local pool per worker at a time: one running and one queued, so a
# worker never waits for this process to build its next group, and a plan is built no further ahead.
IN_FLIGHT_PER_WORKER = 2


def default_workers() -> int:
    """One worker per core: each run is single-threaded (see `PerceptionConfig.threads`)."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def resolve_workers(workers: int | None, address: str | None) -> int | None:
    """The runs at once for a batch: `workers`, or one per core when neither it nor a Ray
    cluster address (whose CPUs then decide) is given; a one-line ConfigError below 1."""
    if workers is None and address is None:
        workers = default_workers()
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    return workers


def check_backend(backend: str, address: str | None = None) -> None:
    """Raise a one-line ConfigError for an unknown backend, an address without Ray, Ray not
    installed, or no Ray cluster at the address; a one-line RenderError where the runs would render
    on this machine (no address) and it cannot render offscreen, which would fail every run."""
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise ConfigError(f"an address ('{address}') is a Ray cluster's; it needs the ray backend (--backend ray)")
    if backend == "ray":
        require_ray()
        if address is not None:
            check_reachable(address)
    if address is None:  # worker processes, or a Ray cluster started here: they render with this machine's EGL
        check_offscreen_rendering()


def run_batch(specs: Iterable[RunSpec], *, workers: int | None = 1, root: str | os.PathLike | None = None,
              on_record: Callable[[dict[str, Any]], None] | None = None, progress: bool = True,
              description: str = "runs", backend: str = "local", address: str | None = None,
              batch: int = DEFAULT_BATCH, total: int | None = None) -> list[dict[str, Any]]:
    """Run every spec; returns their records in the order of `specs`.

    specs: a list, or a `Plan` (or any iterable) whose specs are built only as the workers need
    them: at most a few lock-step groups ahead of the runs (`avsim.experiments.plan`).
    total: how many specs there are, for the progress bar and the group size (default: a plan's
    size, a list's length; an estimate is corrected once the specs run out).
    workers: groups at once. local: processes (1 runs in this process); ray: the local cluster's
    CPUs, or with `address` at most that many tasks in flight (None: twice the cluster's CPUs).
    on_record is called in this process as each run finishes (in finishing order),
    e.g. to append it to a results file. backend, address: see the module docstring.
    batch: runs each local worker or Ray task steps in lock-step (1: one at a time).
    """
    from tqdm import tqdm

    check_backend(backend, address)
    if backend == "local" and (workers is None or workers < 1):
        raise ConfigError(f"the local backend needs workers >= 1, got {workers}")
    if batch < 1:
        raise ConfigError(f"--batch must be >= 1, got {batch}")
    if total is None:
        total = count_of(specs)
    remaining = iter(specs)
    first = next(remaining, None)
    if first is None:
        return []  # nothing to run: no pool, no cluster
    counted = Counted(itertools.chain((first,), remaining))
    root_str = str(root) if root is not None else None
    # With an address and no --workers the cluster's CPUs decide the runs in flight, so the
    # groups are `batch` long; otherwise cut so that each of `workers` gets one.
    groups = lockstep_groups(counted, group_size(total, workers, batch))
    if backend == "ray":
        results = ray_results(groups, root_str, workers=workers, address=address)
    else:
        results = _local_results(groups, workers, root_str)
    bar = tqdm(total=total, desc=description, unit="run", disable=not progress, dynamic_ncols=True)
    records: dict[int, dict[str, Any]] = {}
    failures = 0
    try:
        for index, record in results:
            records[index] = record
            if on_record is not None:
                on_record(record)
            failures += record["status"] == "failed"
            if counted.exhausted and bar.total != counted.count:  # the plan's size was an estimate
                bar.total = counted.count
            bar.set_postfix(failed=failures, refresh=False)
            bar.update(1)
    finally:
        results.close()  # an early stop (an error in on_record, Ctrl-C) cancels the runs not yet started
        bar.close()
    return [records[index] for index in sorted(records)]


def _local_results(groups: Iterator[Group], workers: int, root: str | None) -> Iterator[tuple[int, dict[str, Any]]]:
    """(index into the plan, record) as each run (or lock-step group of runs) finishes: in this
    process, or in a pool of spawned processes fed `IN_FLIGHT_PER_WORKER` groups a worker ahead."""
    if workers <= 1:
        for group in groups:
            yield from _group_records(group, execute_group(specs_of(group), root))
        return
    context = multiprocessing.get_context("spawn")
    # The workers die with this process (a SIGKILL leaves no orphans) and ignore Ctrl-C, which
    # this process handles for them: `avsim.workers`.
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=init_worker,
                               initargs=(worker_env(workers), os.getpid()))
    finished = False
    try:
        for group, future in in_flight(groups, IN_FLIGHT_PER_WORKER * workers,
                                       lambda group: pool.submit(execute_group, specs_of(group), root),
                                       _first_done, Future.cancel):
            yield from _group_records(group, future.result())
        finished = True
    finally:
        if finished:
            pool.shutdown()
        else:  # stopped early (Ctrl-C, an error, the caller closed us): the runs in flight are not awaited
            terminate_workers(pool)


def _first_done(futures: Collection[Future]) -> Future:
    done, _ = wait(futures, return_when=FIRST_COMPLETED)
    return next(iter(done))


def _group_records(group: Group, records: list[dict[str, Any]]) -> Iterator[tuple[int, dict[str, Any]]]:
    yield from zip((index for index, _ in group), records)
