"""Run a leaderboard: its unique configs as one resumable batch, then its manifest and report.

    board = load_leaderboard("experiments/leaderboards/defences.toml")
    run_leaderboard(board, "results/leaderboard", workers=2)

Apart from `avsim.experiments.leaderboard` (the file's format and its matrix) because the report
(`avsim.experiments.leaderboard_report`) reads that matrix, and running writes the report.
"""

from __future__ import annotations

import datetime as dt
import shutil
import time
from pathlib import Path

from avsim.errors import RunsFailedError
from avsim.workers import DEFAULT_BATCH
from avsim.experiments.batch import check_backend, resolve_workers
from avsim.experiments.ray_backend import cluster_nodes
from avsim.software import software_versions
from avsim.experiments.leaderboard import Leaderboard, check_runs_any
from avsim.experiments.leaderboard_report import FIGURE_FILE, REPORT_FILE, write_leaderboard_report
from avsim.experiments.output_lock import locked_output
from avsim.experiments.recordings import (DEFAULT_MCAP, DEFAULT_RRD, check_modes, recording_flags, recording_folders,
                                          with_recordings)
from avsim.experiments.resumable import RESULTS_FILE, existing_records, run_resumable
from avsim.experiments.folder_setting import SETTING_FILE
from avsim.experiments.folder_terms import (LEADERBOARD_COPY, check_made_by, check_resumed_plan, check_resumed_terms,
                                            record_terms)
from avsim.experiments.set_overrides import SET_FILE, flags_of_items
from avsim.experiments.spec import check_renderer
from avsim.metrics import write_json_atomic
from avsim.realism.settings import BASELINE

# Every file a leaderboard writes into its folder (`avsim.experiments.leaderboard`'s docstring), checked before the
# first run: the report is written only after the last one.
FOLDER_FILES = (LEADERBOARD_COPY, RESULTS_FILE, "manifest.json", REPORT_FILE, FIGURE_FILE, SET_FILE, SETTING_FILE)


def run_leaderboard(board: Leaderboard, out_dir: str | Path, *, quick: bool = False, workers: int | None = None,
                    resume: bool = False, progress: bool = True, backend: str = "local",
                    address: str | None = None, batch: int = DEFAULT_BATCH, rrd: str = DEFAULT_RRD,
                    mcap: str = DEFAULT_MCAP) -> Path:
    """Run the board's matrix into `out_dir` (`avsim.experiments.leaderboard`'s docstring lists what
    it writes there); returns `out_dir`. rrd, mcap: which runs are recorded, under OUT/rrd/ and
    OUT/mcap/ (`avsim.experiments.recordings`)."""
    check_backend(backend, address)
    check_renderer(board.base)  # a --setting's keys are in the base config, set after loading checked every run
    check_modes(rrd, mcap)
    check_runs_any(board, quick)
    out = Path(out_dir)
    workers = resolve_workers(workers, address)
    check_made_by(out, "avsim leaderboard")
    if resume:
        check_resumed_terms(out, board, "avsim leaderboard")
    # One command at a time in `out`; a folder made here and left without a record is removed.
    with locked_output(out, f"avsim leaderboard {board.path} --out {out}", results_name=RESULTS_FILE,
                       files=FOLDER_FILES, folders=recording_folders([board.name], rrd=rrd, mcap=mcap)):
        return _run_leaderboard_locked(board, out, quick=quick, workers=workers, resume=resume, progress=progress,
                                       backend=backend, address=address, batch=batch, rrd=rrd, mcap=mcap)


def _run_leaderboard_locked(board: Leaderboard, out: Path, *, quick: bool, workers: int | None, resume: bool,
                            progress: bool, backend: str, address: str | None, batch: int, rrd: str, mcap: str) -> Path:
    results_path = out / RESULTS_FILE
    existing = existing_records(results_path, resume)
    check_resumed_plan(out, existing, board.path, board.name, LEADERBOARD_COPY)
    # The distinct configs are built as the batch draws on them, never all at once.
    plan = board.plan(quick).then(lambda specs: with_recordings(specs, out, rrd=rrd, mcap=mcap))
    options = ["--quick" if quick else "", f"--workers {workers}" if workers is not None else "",
               f"--batch {batch}" if batch != DEFAULT_BATCH else "",
               f"--backend {backend}" if backend != "local" else "", f"--address {address}" if address is not None else "",
               f"--setting {board.setting}" if board.setting != BASELINE else "", flags_of_items(dict(board.set_items))]
    command = " ".join([f"avsim leaderboard {board.path} --out {out}", *filter(None, options)]) + recording_flags(rrd, mcap)

    started = time.perf_counter()
    started_at = dt.datetime.now().astimezone()
    out.mkdir(parents=True, exist_ok=True)
    if board.path.resolve() != (out / LEADERBOARD_COPY).resolve():
        shutil.copy2(board.path, out / LEADERBOARD_COPY)
    record_terms(out, board)
    nodes = cluster_nodes(backend, address)
    records, ran = run_resumable(plan, results_path, existing, resume_command=f"{command} --resume", workers=workers,
                                 progress=progress, description="leaderboard", backend=backend, address=address,
                                 batch=batch)
    manifest = {
        "command": command + (" --resume" if resume else ""),
        "started_at": started_at.isoformat(timespec="seconds"),
        "title": board.title,
        "wall_s": round(time.perf_counter() - started, 1),
        "backend": backend,
        "address": address,
        "workers": workers,
        "quick": quick,
        "runs": plan.size,
        "configs": len(records),
        "ran": ran,
        "reused": len(records) - ran,
        "failed": sum(1 for r in records if r["status"] == "failed"),
        "versions": software_versions(),
        "cluster_nodes": nodes,
    }
    write_json_atomic(out / "manifest.json", manifest)
    write_leaderboard_report(out, board, board.iter_runs(quick), records, manifest)
    if records and manifest["failed"] == len(records):
        first = next(r["error"] for r in records if r["status"] == "failed")
        raise RunsFailedError(f"every one of the {len(records)} runs failed (the first: {first}); see {out / 'leaderboard.md'}")
    return out
