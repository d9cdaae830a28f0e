"""One run of a batch, as a worker process executes it: the spec, the run, and its JSON record.

    record = execute(RunSpec("table3_stop_positions", "baseline, Town07 standard", 0, config), root)

Both batch backends (`avsim.experiments.batch`'s local pool and `avsim.experiments.ray_backend`)
run `execute` for each spec; it lives here, apart from both, because each backend needs it and the
batch needs both backends.

A record (a JSON-ready dict, one line of `runs.jsonl`):
    experiment, cell, seed    where the run comes from
    spec_hash                 sha256 of the run's resolved config and its sign texture's bytes
                              (the same config on the same pixels, the same hash)
    status                    "ok" or "failed"; error: "ExceptionType: message" when failed
    result                    the `RunResult` JSON of `avsim run --json` (config included), or null
    trace                     per control step: sign_dist_m [m, bumper to sign], speed_mps,
                              brake [0..1], and per camera the policy rendered, <camera>_conf:
                              its best stop-sign confidence (0 when it reported none)
    rrd, mcap                 paths of the run's rerun recording and ROS 2 bag, relative to the batch
                              folder, or null where none was asked for (`avsim.experiments.recordings`)
    wall_s                    wall-clock time of the run [s]
"""

from __future__ import annotations

import hashlib
import json
import os
import traceback
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.config import NO_SIGN, SimConfig
from avsim.control.policies import POLICIES, STOP_CLASS
from avsim.errors import ConfigError
from avsim.experiments.failures import is_failed_run
from avsim.metrics import StepRecord
from avsim.lockstep import run_lockstep
from avsim.runner import RunOutput, run_recorded
from avsim.termination import raise_if_interrupted
from avsim.world.scene import resolve_sign_texture

# Trace values are rounded to keep runs.jsonl small; far below anything a figure shows.
_TRACE_DECIMALS = 4


@dataclass(frozen=True)
class RunSpec:
    """One run of a batch: where it comes from, its config, and where its recording goes.

    rrd_path, mcap_path: absolute paths of the `.rrd` and `.mcap` to write, or None for none.
    rrd_when, mcap_when: "all" keeps the recording; "failed" only if the run's car failed
    (`avsim.experiments.failures`).
    """

    experiment: str
    cell: str
    seed: int
    config: SimConfig
    rrd_path: str | None = None
    mcap_path: str | None = None
    rrd_when: str = "all"
    mcap_when: str = "all"

    @property
    def spec_hash(self) -> str:
        """Hash of the run's resolved config (`config_hash`): the key a resumed batch matches runs by."""
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
    try:
        output: RunOutput | Exception = run_recorded(spec.config, **recording_of(spec))
    except Exception as exc:  # noqa: BLE001 - recorded as a failed run, counted and reported
        raise_if_interrupted(exc)  # a Ctrl-C that a C call wrapped stops the batch, as any Ctrl-C does
        output = exc
    return record_of(spec, output, root)


def execute_many(specs: Sequence[RunSpec], root: str | None = None) -> list[dict[str, Any]]:
    """Run the specs in lock-step in this process (`avsim.lockstep`: one network call per control
    tick over all their cars) and return their records, in order: each the record `execute` gives
    that spec alone, `wall_s` aside (a run's share of the batch's time)."""
    outputs = run_lockstep([spec.config for spec in specs], recordings=[recording_of(spec) for spec in specs])
    return [record_of(spec, output, root) for spec, output in zip(specs, outputs)]


def execute_group(specs: Sequence[RunSpec], root: str | None = None) -> list[dict[str, Any]]:
    """The records of one lock-step group, in order: a lone run as `execute` runs it, more in
    lock-step (`execute_many`); a pool worker's or a Ray task's unit of work."""
    return [execute(specs[0], root)] if len(specs) == 1 else execute_many(specs, root)


def record_of(spec: RunSpec, output: RunOutput | Exception, root: str | None = None) -> dict[str, Any]:
    """The record of a spec's finished run, or of the exception that ended it (a failed record)."""
    if isinstance(output, Exception):
        last = traceback.extract_tb(output.__traceback__)[-1] if output.__traceback__ else None
        where = f" (at {Path(last.filename).name}:{last.lineno})" if last else ""
        return failed_record(spec, f"{type(output).__name__}: {output}{where}")
    record = _blank_record(spec)
    # The policy classes declare the cameras they render; the trace has a series for each.
    cameras = POLICIES.get(spec.config.policy.name).cameras
    record.update(result=output.result.to_json_dict(), trace=trace_of(output.records, cameras),
                  wall_s=round(output.wall_s, 3))
    failed = is_failed_run(output.result)
    for kind in _recorded_kinds(spec):
        if getattr(spec, f"{kind}_when") == "all" or failed:  # the recordings `recording_of` kept
            path = getattr(spec, f"{kind}_path")
            record[kind] = os.path.relpath(path, root) if root else path
    return record


def _recorded_kinds(spec: RunSpec) -> list[str]:
    return [kind for kind in ("rrd", "mcap") if getattr(spec, f"{kind}_path")]


def recording_of(spec: RunSpec) -> dict[str, Any]:
    """`run_recorded`'s recording arguments for the spec, as its `*_when` fields ask: every recorder
    asked for records the run; one asked for failed runs only is discarded when the car did not
    fail (`avsim.experiments.failures`)."""
    kinds = _recorded_kinds(spec)
    only_failed = {kind: is_failed_run for kind in kinds if getattr(spec, f"{kind}_when") == "failed"}
    return {**{f"{kind}_path": getattr(spec, f"{kind}_path") for kind in kinds}, "keep_if": only_failed}


def _blank_record(spec: RunSpec) -> dict[str, Any]:
    return {"experiment": spec.experiment, "cell": spec.cell, "seed": spec.seed, "spec_hash": spec.spec_hash,
            "status": "ok", "error": None, "result": None, "trace": None, "rrd": None, "mcap": None,
            "wall_s": None}


def failed_record(spec: RunSpec, error: str) -> dict[str, Any]:
    """The record of a run that did not finish; error: "ExceptionType: message"."""
    return {**_blank_record(spec), "status": "failed", "error": error}


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
