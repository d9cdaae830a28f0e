"""SIGTERM (a scheduler, `timeout`, `docker stop`) and SIGHUP are handled as Ctrl-C is
(`avsim.termination`): one line, exit 128 + the signal, temporaries removed, finished runs kept,
and a resume loses nothing. The signal goes to the avsim process alone, as `kill PID` sends it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from avsim.experiments.results_file import read_records
from helpers import REPO, start_avsim, wait_until

SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"
TIMEOUT_S = 120.0  # for a signalled process to exit
RUN_ARGS = ["--perception", "oracle", "--set", "scenario.start_dist_m=100"]


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if ".tmp" in p.name)


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 143), (signal.SIGHUP, 129)], ids=["SIGTERM", "SIGHUP"])
def test_a_signal_during_run_rrd_is_one_line_and_leaves_no_temporary(tmp_path, signum, status):
    out = tmp_path / "out"
    out.mkdir()
    log = tmp_path / "stderr.log"
    proc = start_avsim(["run", *RUN_ARGS, "--rrd", str(out / "a.rrd"), "--json", str(out / "a.json")], log)
    wait_until(lambda: len(_temporaries(out)) == 1, proc, "the recorder started", log)
    time.sleep(0.3)  # some frames into the recording
    proc.send_signal(signum)
    assert proc.wait(timeout=TIMEOUT_S) == status, log.read_text()
    err = log.read_text()
    assert len(err.splitlines()) == 1 and f"terminated ({signal.Signals(signum).name})" in err, err
    assert list(out.iterdir()) == []  # no recording, no record, no temporary


@pytest.mark.slow  # about 45 s: a reference sweep, the terminated one, and its resumption
def test_sigterm_during_a_sweep_keeps_the_finished_runs_and_a_resume_loses_nothing(tmp_path):
    reference = tmp_path / "reference"
    subprocess.run([sys.executable, "-m", "avsim", "sweep", str(SMOKE), "--out", str(reference), "--workers", "1",
                    "--no-progress"], cwd=REPO, check=True, capture_output=True, timeout=300)
    expected = read_records(reference / "results.jsonl")

    out, log = tmp_path / "terminated", tmp_path / "stderr.log"
    results = out / "results.jsonl"
    # --batch 1: runs finish one at a time. In lock-step groups (two runs a worker) the four records
    # arrive as two near-simultaneous pairs, and the signal could land after the last of them.
    argv = ["sweep", str(SMOKE), "--out", str(out), "--workers", "2", "--batch", "1", "--no-progress"]
    proc = start_avsim(argv, log)
    wait_until(lambda: results.exists() and results.read_text().count("\n") >= 1, proc, "its first record", log)
    proc.send_signal(signal.SIGTERM)  # the main process only, as a scheduler sends it
    assert proc.wait(timeout=TIMEOUT_S) == 143
    lines = log.read_text().splitlines()
    assert len(lines) == 1 and "terminated (SIGTERM)" in lines[0] and "--resume" in lines[0], lines
    kept = read_records(results)
    assert 1 <= len(kept) < 4 and _temporaries(out) == []

    resumed = subprocess.run([sys.executable, "-m", "avsim", *argv, "--resume"], cwd=REPO, capture_output=True,
                             text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    strip = lambda records: [{k: v for k, v in r.items() if k != "wall_s"} for r in records]  # noqa: E731
    assert strip(read_records(results)) == strip(expected)
    assert os.path.exists(out / "summary.md")


def _ctypes_error_of(interruption: BaseException) -> Exception:
    """What ctypes raises when `interruption` lands while it converts a C call's argument (as under
    PyOpenGL's EGL calls): an ArgumentError that only names it."""
    import ctypes

    class Raising:
        @classmethod
        def from_param(cls, value):
            raise interruption

    call = ctypes.CDLL(None).abs
    call.argtypes = [Raising]
    try:
        call(1)
    except ctypes.ArgumentError as exc:
        return exc
    raise AssertionError("ctypes did not wrap the interruption")


def test_a_ctrl_c_that_ctypes_wrapped_stops_the_command_as_ctrl_c_not_as_a_broken_egl(monkeypatch, capsys):
    import mujoco

    from avsim import boundary
    from avsim.sensors import gl
    from avsim.termination import raise_if_interrupted

    wrapped = _ctypes_error_of(KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        raise_if_interrupted(wrapped)
    raise_if_interrupted(_ctypes_error_of(ValueError("bad argument")))  # a real error stays one
    raise_if_interrupted(RuntimeError("no display"))

    def gl_start_hit_by_ctrl_c(*args):
        raise wrapped

    monkeypatch.setattr(gl.mujoco, "GLContext", gl_start_hit_by_ctrl_c)
    with pytest.raises(KeyboardInterrupt):  # was: a RenderError, "cannot start offscreen rendering", exit 2
        gl.OffscreenRenderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 64, 48, segmentation=False)
    assert boundary.run_guarded(lambda: gl.OffscreenRenderer(None, 64, 48, segmentation=False)) == 130
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "interrupted" in err, err
