"""Run many closed-loop configs in worker processes; each finished run is one JSON record.

    specs = [RunSpec("table3_stop_positions", run.cell_name, run.seed, run.config) for run in experiment.runs()]
    records = run_batch(specs, workers=2, on_record=writer.append)
    records = run_batch(specs, workers=2, backend="ray")     # the same runs as Ray tasks

Every run is `avsim.runner.run_recorded`, exactly what `avsim run` executes, so one record
can be re-run alone with `avsim run --config FILE --cell NAME --seed K`. A run that raises
becomes a `failed` record carrying the error, and the batch goes on.

Backends (`BACKENDS`); both run `execute(spec, root)` for each spec:
    local   this process (workers 1) or a pool of `workers` `spawn`ed processes on this
            machine; each builds its own MuJoCo model and EGL context (an OpenGL context
            must never cross a fork). A worker process that dies stops the batch. The
            workers exit when this process dies, and a batch stopped early (Ctrl-C)
            stops them at once rather than waiting for their runs (`avsim.workers`).
    ray     Ray tasks on a cluster, or on a local one of `workers` CPUs
            (`avsim.experiments.ray_backend`, an optional extra: pip install 'avsim[ray]').
Records, `on_record` and the progress bar are one code path for both.

A record (`RunRecord.to_json_dict`, one line of `runs.jsonl`):
    experiment, cell, seed    where the run comes from
    spec_hash                 sha256 of the run's resolved config and its sign texture's bytes
                              (the same config on the same pixels, the same hash)
    status                    "ok" or "failed"; error: "ExceptionType: message" when failed
    result                    the `RunResult` JSON of `avsim run --json` (config included), or null
    trace                     per control step: sign_dist_m [m, bumper to sign], speed_mps,
                              brake [0..1], and per camera the policy rendered, <camera>_conf:
                              its best stop-sign confidence (0 when it reported none)
    rrd                       path of the run's rerun recording, relative to the batch folder
    wall_s                    wall-clock time of the run [s]
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.config import NO_SIGN, SimConfig
from avsim.control.policies import STOP_CLASS
from avsim.errors import ConfigError
from avsim.metrics import StepRecord
from avsim.workers import init_worker, terminate_workers
from avsim.world.scene import resolve_sign_texture

# Trace values are rounded to keep runs.jsonl small; far below anything a figure shows.
_TRACE_DECIMALS = 4
BACKENDS = ("local", "ray")


@dataclass(frozen=True)
class RunSpec:
    """One run of a batch: where it comes from, its config, and where its recording goes.

    rrd_path: absolute path of the `.rrd` to write, or None for no recording.
    """

    experiment: str
    cell: str
    seed: int
    config: SimConfig
    rrd_path: str | None = None

    @property
    def spec_hash(self) -> str:
        return config_hash(self.config)


def config_hash(config: SimConfig) -> str:
    """sha256 of the config's canonical JSON and of the sign texture's bytes: identical configs on
    identical pixels give identical hashes.

    A config names its texture (`scenario.sign = "driveby_detector"`); the pixels are in the file.
    A texture made again under the same name must change the hash, or `--resume` would reuse the
    runs of the old one as if they were of the new one.
    """
    payload = {"config": config.to_dict(), "sign_texture_sha256": _sign_texture_sha256(config.scenario.sign)}
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def _sign_texture_sha256(sign: str) -> str | None:
    """sha256 of the sign's texture file; None for no sign, or a texture that cannot be read (the
    run itself then fails with the loader's one-line error, recorded as a failed run)."""
    if sign == NO_SIGN:
        return None
    try:
        return hashlib.sha256(resolve_sign_texture(sign).read_bytes()).hexdigest()
    except (ConfigError, OSError):
        return None


def trace_of(records: Sequence[StepRecord], cameras: Iterable[str]) -> dict[str, list[float]]:
    """The per-step series a report plots (see the module docstring for the keys)."""
    trace: dict[str, list[float]] = {
        "sign_dist_m": [round(r.sign_dist_m, _TRACE_DECIMALS) for r in records],
        "speed_mps": [round(r.speed_mps, _TRACE_DECIMALS) for r in records],
        "brake": [round(r.brake, _TRACE_DECIMALS) for r in records],
    }
    for camera in cameras:
        trace[f"{camera}_conf"] = [
            round(max((d.confidence for d in r.detections if d.camera == camera and d.class_name == STOP_CLASS),
                      default=0.0), _TRACE_DECIMALS)
            for r in records]
    return trace


def execute(spec: RunSpec, root: str | None = None) -> dict[str, Any]:
    """Run one spec and return its record (a failure is a record too). Runs in a worker process.

    root: the batch folder; the record's `rrd` path is written relative to it.
    """
    # Imported here: workers are spawned, and the policy registry pulls in the whole loop.
    from avsim.control.policies import POLICIES
    from avsim.runner import run_recorded

    record = _blank_record(spec)
    try:
        output = run_recorded(spec.config, rrd_path=spec.rrd_path)
    except Exception as exc:  # noqa: BLE001 - recorded as a failed run, counted and reported
        last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
        where = f" (at {Path(last.filename).name}:{last.lineno})" if last else ""
        return failed_record(spec, f"{type(exc).__name__}: {exc}{where}")
    # The policy classes declare the cameras they render; the trace has a series for each.
    cameras = POLICIES.get(spec.config.policy.name).cameras
    record.update(result=output.result.to_json_dict(), trace=trace_of(output.records, cameras),
                  wall_s=round(output.wall_s, 3))
    if spec.rrd_path:
        record["rrd"] = os.path.relpath(spec.rrd_path, root) if root else spec.rrd_path
    return record


def _blank_record(spec: RunSpec) -> dict[str, Any]:
    return {"experiment": spec.experiment, "cell": spec.cell, "seed": spec.seed, "spec_hash": spec.spec_hash,
            "status": "ok", "error": None, "result": None, "trace": None, "rrd": None, "wall_s": None}


def failed_record(spec: RunSpec, error: str) -> dict[str, Any]:
    """The record of a run that did not finish; error: "ExceptionType: message"."""
    return {**_blank_record(spec), "status": "failed", "error": error}


def check_backend(backend: str, address: str | None = None) -> None:
    """Raise a one-line ConfigError for an unknown backend, an address without Ray, Ray not
    installed, or no Ray cluster at the address."""
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise ConfigError(f"an address ('{address}') is a Ray cluster's; it needs the ray backend (--backend ray)")
    if backend == "ray":
        from avsim.experiments.ray_backend import check_reachable, require_ray

        require_ray()
        if address is not None:
            check_reachable(address)


def run_batch(specs: Sequence[RunSpec], *, workers: int | None = 1, root: str | os.PathLike | None = None,
              on_record: Callable[[dict[str, Any]], None] | None = None, progress: bool = True,
              description: str = "runs", backend: str = "local", address: str | None = None) -> list[dict[str, Any]]:
    """Run every spec; returns their records in the order of `specs`.

    workers: runs at once. local: processes (1 runs in this process); ray: the local cluster's
    CPUs, or with `address` at most that many runs in flight (None: as many as the cluster
    takes). on_record is called in this process as each run finishes (in finishing order),
    e.g. to append it to a results file. backend, address: see the module docstring.
    """
    from tqdm import tqdm

    check_backend(backend, address)
    if backend == "local" and (workers is None or workers < 1):
        raise ConfigError(f"the local backend needs workers >= 1, got {workers}")
    if not specs:
        return []  # nothing to run: no pool, no cluster
    root_str = str(root) if root is not None else None
    records: list[dict[str, Any] | None] = [None] * len(specs)
    if backend == "ray":
        from avsim.experiments.ray_backend import ray_results

        results = ray_results(specs, root_str, workers=workers, address=address)
    else:
        results = _local_results(specs, workers, root_str)
    bar = tqdm(total=len(specs), desc=description, unit="run", disable=not progress, dynamic_ncols=True)
    failures = 0
    try:
        for index, record in results:
            records[index] = record
            if on_record is not None:
                on_record(record)
            failures += record["status"] == "failed"
            bar.set_postfix(failed=failures, refresh=False)
            bar.update(1)
    finally:
        results.close()  # an early stop (an error in on_record, Ctrl-C) cancels the runs not yet started
        bar.close()
    return [r for r in records if r is not None]


def worker_env(workers: int) -> dict[str, str]:
    """Environment for one of `workers` run processes on this machine: its share of the cores.

    Mesa's llvmpipe rasterises on as many threads as the machine has cores (LP_NUM_THREADS);
    with one such renderer per worker the workers' threads fight over the cores. Each worker
    gets cores // workers threads instead. The thread count does not change a pixel: the
    image is cut into tiles that each thread draws the same way. A user's own
    LP_NUM_THREADS wins.
    """
    if "LP_NUM_THREADS" in os.environ:
        return {}
    return {"LP_NUM_THREADS": str(max(1, (os.cpu_count() or 1) // max(1, workers)))}


def _local_results(specs: Sequence[RunSpec], workers: int, root: str | None) -> Iterator[tuple[int, dict[str, Any]]]:
    """(index into specs, record) as each run finishes: in this process, or in a pool of spawned processes."""
    if workers <= 1:
        for index, spec in enumerate(specs):
            yield index, execute(spec, root)
        return
    context = multiprocessing.get_context("spawn")
    # The workers die with this process (a SIGKILL leaves no orphans) and ignore Ctrl-C, which
    # this process handles for them: `avsim.workers`.
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=init_worker,
                               initargs=(worker_env(workers), os.getpid()))
    finished = False
    try:
        futures = {pool.submit(execute, spec, root): index for index, spec in enumerate(specs)}
        for future in as_completed(futures):
            yield futures[future], future.result()
        finished = True
    finally:
        if finished:
            pool.shutdown()
        else:  # stopped early (Ctrl-C, an error, the caller closed us): the runs in flight are not awaited
            terminate_workers(pool)
