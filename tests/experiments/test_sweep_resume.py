"""A sweep SIGKILLed at any moment, then resumed, ends with the results.jsonl of a sweep never stopped.

The sweep runs as `python -m avsim sweep ... --workers 1` in a subprocess (one process: the
kill stops every run). It is killed right after its first record lands; a torn line is
appended, as a kill in the middle of a write leaves; resumed, it is killed at a seeded random
moment of a run; a last `--resume` finishes it.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
import time
from pathlib import Path

import pytest

from avsim import cli
from avsim.experiments.results_file import read_records
from helpers import wait_until

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"
TIMEOUT_S = 120.0  # per subprocess; the whole sweep takes a fraction of it


def _start(out: Path, log: Path, resume: bool) -> subprocess.Popen:
    # --batch 1: one run after another, so a kill can fall between two records (a lock-step batch of
    # four would write all four at its end).
    command = [sys.executable, "-m", "avsim", "sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--batch", "1",
               "--no-progress"]
    with log.open("ab") as stderr:
        return subprocess.Popen(command + (["--resume"] if resume else []), cwd=REPO, stdout=subprocess.DEVNULL,
                                stderr=stderr)


def _complete_lines(path: Path) -> list[str]:
    if not path.exists():
        return []
    return [line for line in path.read_text().splitlines(keepends=True) if line.endswith("\n")]


def _wait_for_lines(proc: subprocess.Popen, path: Path, count: int, log: Path) -> None:
    wait_until(lambda: len(_complete_lines(path)) >= count, proc, f"writing {count} records", log, TIMEOUT_S)


def _kill(proc: subprocess.Popen) -> None:
    proc.kill()  # SIGKILL: no cleanup, no flush, as a crash or an OOM kill
    proc.wait()


def _without_wall_time(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in records]


@pytest.mark.slow  # 23 s: a whole sweep twice
def test_a_killed_sweep_resumes_to_the_results_of_one_never_stopped(tmp_path):
    reference = tmp_path / "reference"
    assert cli.main(["sweep", str(SMOKE), "--out", str(reference), "--workers", "1", "--no-progress"]) == 0
    expected = read_records(reference / "results.jsonl")

    out, log = tmp_path / "killed", tmp_path / "stderr.log"
    results = out / "results.jsonl"

    # 1. Killed as soon as its first run is on disk.
    proc = _start(out, log, resume=False)
    _wait_for_lines(proc, results, 1, log)
    _kill(proc)
    assert len(read_records(results)) == 1

    # 2. A kill in the middle of a write leaves a torn last line.
    first = _complete_lines(results)[0]
    with results.open("a") as f:
        f.write(first[: len(first) // 2])

    # 3. Resumed, and killed in the middle of its second run, at a seeded random moment of it.
    run_s = sum(r["wall_s"] for r in expected) / len(expected)
    proc = _start(out, log, resume=True)
    _wait_for_lines(proc, results, 2, log)  # the torn line was dropped, one more run is on disk
    time.sleep(random.Random(6).uniform(0.1, 0.9) * run_s)
    _kill(proc)
    lines = _complete_lines(results)
    assert 2 <= len(lines) < 4
    for line in lines:
        json.loads(line)  # a whole record each: none was glued onto the torn line

    # 4. Resumed to the end.
    proc = _start(out, log, resume=True)
    assert proc.wait(timeout=TIMEOUT_S) == 0, log.read_text()

    text = results.read_text()
    assert text.endswith("\n")
    records = [json.loads(line) for line in text.splitlines()]  # no torn line anywhere
    hashes = [r["spec_hash"] for r in records]
    assert len(hashes) == len(set(hashes)) == 4  # no run recorded twice
    assert set(hashes) == {r["spec_hash"] for r in expected}
    assert _without_wall_time(records) == _without_wall_time(expected)
