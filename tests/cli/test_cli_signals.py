"""Ctrl-C and SIGKILL against real `avsim` processes.

- Ctrl-C (SIGINT to the whole process group, as a terminal sends it) during `avsim run` or a
  sweep: exit 130, at most 3 lines on stderr, nothing half-written; running again, or resuming
  the sweep, gives the records of a run never stopped.
- SIGKILL during `avsim run` with all three outputs leaves temporary files, and the next run of
  the same outputs removes them.
- SIGKILL of a sweep's main process: no worker outlives it by more than 10 s.
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

from avsim import cli
from avsim.config import SimConfig, with_overrides
from avsim.experiments.results_file import read_records
from avsim.runner import run_config
from helpers import start_avsim, wait_until

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"
TIMEOUT_S = 120.0
# A short oracle run: 100 m from rest at 85 km/h, a few seconds of wall time.
RUN_ARGS = ["--perception", "oracle", "--set", "scenario.start_dist_m=100"]
ORPHAN_LIMIT_S = 10.0


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and ".tmp" in p.name)


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid` (from /proc)."""
    children = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                children.append(int(entry.name))
    return children


def _cmdline(pid: int) -> bytes:
    """The command line of process `pid`, or b"" once it has exited: a short-lived child may go between
    `_children` listing it and this reading it."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited; it only waits to be reaped


def _wait_gone(pids: list[int], limit_s: float) -> list[int]:
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def _oracle_result() -> dict:
    config = with_overrides(SimConfig(), {"perception": {"kind": "oracle"}, "scenario": {"start_dist_m": 100.0}})
    return json.loads(json.dumps(run_config(config)[0].to_json_dict()))  # as JSON has it: tuples are lists


def test_ctrl_c_during_run_is_one_line_exit_130_and_nothing_written(tmp_path):
    outputs = ["--json", str(tmp_path / "a.json"), "--rrd", str(tmp_path / "a.rrd"), "--mp4", str(tmp_path / "a.mp4")]
    log = tmp_path.parent / f"{tmp_path.name}.err"
    proc = start_avsim(["run", *RUN_ARGS, *outputs], log)
    wait_until(lambda: len(_temporaries(tmp_path)) == 2, proc, "the recorders started", log)
    os.killpg(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=TIMEOUT_S) == 130
    err = log.read_text()
    assert 1 <= len(err.splitlines()) <= 3 and "interrupted" in err and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []  # no output, no temporary file

    # Run again: the same record as a run never stopped.
    assert cli.main(["run", *RUN_ARGS, *outputs]) == 0
    assert json.loads((tmp_path / "a.json").read_text()) == _oracle_result()


def test_a_killed_runs_temporary_files_are_removed_by_the_next_run(tmp_path):
    outputs = ["--json", str(tmp_path / "a.json"), "--rrd", str(tmp_path / "a.rrd"), "--mp4", str(tmp_path / "a.mp4")]
    log = tmp_path.parent / f"{tmp_path.name}.err"
    proc = start_avsim(["run", *RUN_ARGS, *outputs], log)
    wait_until(lambda: len(_temporaries(tmp_path)) == 2, proc, "the recorders started", log)
    time.sleep(0.5)  # some frames into each file
    proc.kill()  # SIGKILL: no cleanup, as the OOM killer does it
    proc.wait()
    left = _temporaries(tmp_path)
    assert len(left) == 2 and not (tmp_path / "a.json").exists()  # what a kill leaves

    assert cli.main(["run", *RUN_ARGS, *outputs]) == 0
    assert _temporaries(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "a.mp4", "a.rrd"]


@pytest.mark.slow  # about 25 s: a reference sweep, then the interrupted one and its resumption
def test_ctrl_c_during_a_sweep_says_how_to_resume_and_resuming_gives_the_same_records(tmp_path):
    reference = tmp_path / "reference"
    assert cli.main(["sweep", str(SMOKE), "--out", str(reference), "--workers", "1", "--no-progress"]) == 0
    expected = read_records(reference / "results.jsonl")

    out, log = tmp_path / "interrupted", tmp_path / "stderr.log"
    results = out / "results.jsonl"
    # --batch 1: each worker runs one at a time, so Ctrl-C can land between records.
    argv = ["sweep", str(SMOKE), "--out", str(out), "--workers", "2", "--batch", "1", "--no-progress"]
    proc = start_avsim(argv, log)
    wait_until(lambda: results.exists() and results.read_text().count("\n") >= 1, proc, "its first record", log)
    workers = _children(proc.pid)
    os.killpg(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=TIMEOUT_S) == 130
    err = log.read_text()
    lines = err.splitlines()
    assert 1 <= len(lines) <= 3 and "Traceback" not in err, err
    assert f"resume with: avsim sweep {SMOKE} --out {out} --resume" in lines[-1]
    assert _wait_gone(workers, 5.0) == []
    assert 1 <= len(read_records(results)) < 4

    proc = start_avsim([*argv, "--resume"], log)
    assert proc.wait(timeout=TIMEOUT_S) == 0, log.read_text()
    strip = lambda rs: [{k: v for k, v in r.items() if k != "wall_s"} for r in rs]  # noqa: E731
    assert strip(read_records(results)) == strip(expected)
    assert _temporaries(out) == []


@pytest.mark.slow  # about 55 s: two reproductions with two workers each; the default pass keeps Ctrl-C during a run
def test_ctrl_c_during_reproduce_stops_its_workers_and_the_command_it_names_finishes_the_reproduction(tmp_path):
    experiment = tmp_path / "table3_stop_positions.toml"
    experiment.write_text("""
title = "t"
seeds = 4
[defaults]
scenario = { town = "town07", placement = "standard", start_dist_m = 100 }
perception = { kind = "oracle" }
[[cells]]
name = "clean sign, baseline"
""")
    log, root = tmp_path / "stderr.log", tmp_path / "results"
    proc = start_avsim(["reproduce", "--experiments", str(experiment), "--workers", "2", "--no-progress", "--out", str(root)], log)

    def one_finished() -> bool:
        runs = list(root.glob("*/runs.jsonl"))
        return bool(runs) and runs[0].read_text().count("\n") >= 1

    wait_until(one_finished, proc, "its first run finished", log)
    workers = _children(proc.pid)
    os.killpg(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=TIMEOUT_S) == 130
    err = log.read_text()
    assert len(err.splitlines()) == 1 and "resume with: avsim reproduce --experiments" in err, err
    assert _wait_gone(workers, 5.0) == []
    recordings = [p.name for p in root.rglob("*") if p.is_file() and p.suffix != ".jsonl" and p.suffix != ".toml"]
    assert all(name.endswith(".rrd") and not name.startswith(".") for name in recordings), recordings

    (folder,) = root.iterdir()
    kept = read_records(folder / "runs.jsonl")
    resume_argv = err.split("resume with: avsim ", 1)[1].split()
    assert resume_argv[-2:] == ["--resume", str(folder)], err
    proc = start_avsim([*resume_argv, "--workers", "2", "--no-progress"], log)
    assert proc.wait(timeout=TIMEOUT_S) == 0, log.read_text()
    records = read_records(folder / "runs.jsonl")
    assert [r["seed"] for r in records] == [0, 1, 2, 3] and all(r["status"] == "ok" for r in records)
    by_seed = {r["seed"]: r for r in records}
    assert kept and all(by_seed[k["seed"]] == k for k in kept)  # kept as they were, not run again
    assert json.loads((folder / "manifest.json").read_text())["reused"] == len(kept)


def _kill_sweep_and_time_its_workers(tmp_path: Path, backend_args: list[str], worker_pids) -> None:
    """SIGKILL a sweep's main process once its runs are under way; its workers must be gone within 10 s."""
    sweep = tmp_path / "long.toml"
    sweep.write_text(SMOKE.read_text().replace('"scenario.speed_kmh" = [40, 60]', '"scenario.speed_kmh" = [40, 50, 60, 70]')
                     .replace("seeds = 1", "seeds = 4"))
    log = tmp_path / "stderr.log"
    proc = start_avsim(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--workers", "2", "--no-progress",
                   *backend_args], log)
    found: list[int] = []

    def running() -> bool:
        found[:] = worker_pids(proc.pid)
        return len(found) >= 2

    wait_until(running, proc, "two workers were running", log)
    time.sleep(2.0)  # into their runs
    proc.kill()
    proc.wait()
    survivors = _wait_gone(found, ORPHAN_LIMIT_S)
    for pid in survivors:  # do not leave them to the machine
        os.kill(pid, signal.SIGKILL)
    assert survivors == [], f"workers {survivors} outlived their sweep by more than {ORPHAN_LIMIT_S:g} s"


def test_no_pool_worker_outlives_a_killed_sweep(tmp_path):
    def pool_workers(pid: int) -> list[int]:
        return [c for c in _children(pid) if b"spawn_main" in _cmdline(c)]

    _kill_sweep_and_time_its_workers(tmp_path, [], pool_workers)


@pytest.mark.slow
@pytest.mark.usefixtures("one_local_ray_cluster_at_a_time")
def test_no_ray_worker_outlives_a_killed_sweep(tmp_path):
    pytest.importorskip("ray")

    def ray_workers(pid: int) -> list[int]:
        # Ray's task workers are the raylet's children named ray::execute; the raylet is the driver's child.
        return [w for raylet in _children(pid) for w in _children(raylet)
                if _cmdline(w).startswith(b"ray::execute")]

    _kill_sweep_and_time_its_workers(tmp_path, ["--backend", "ray"], ray_workers)
