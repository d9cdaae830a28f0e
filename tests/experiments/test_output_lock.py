"""One command per results folder (`avsim.experiments.output_lock`), and what a failed start leaves."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from avsim import cli
from avsim.errors import OutputError
from avsim.experiments.output_lock import LOCK_NAME, check_writable, locked_output, locked_sibling
from avsim.experiments.results_file import read_records

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"


def test_a_second_holder_is_refused_naming_the_first(tmp_path):
    with locked_output(tmp_path / "out", "avsim sweep first.toml"):
        with pytest.raises(OutputError) as refused:
            with locked_output(tmp_path / "out", "avsim sweep second.toml"):
                pass
    message = str(refused.value)
    assert "\n" not in message and f"pid {os.getpid()}" in message and "first.toml" in message
    with locked_output(tmp_path / "out", "avsim sweep third.toml"):  # released: free again
        pass


def test_a_sibling_lock_refuses_a_second_writer_of_a_file_or_folder_made_later(tmp_path):
    target = tmp_path / "sub" / "data"  # neither exists yet: make-data renames its folder into place
    with locked_sibling(target, "avsim detector make-data --out first"):
        with pytest.raises(OutputError) as refused:
            with locked_sibling(target, "second"):
                pass
    message = str(refused.value)
    assert "\n" not in message and str(target) in message and "make-data --out first" in message
    assert list((tmp_path / "sub").iterdir()) == []  # the lock file goes with its holder
    with locked_sibling(target, "third"):
        pass


# Every command that writes a report folder (or makes a dataset) is refused, before its work, while
# another command holds its --out: (argv without --out, how the output is held).
HELD_OUTPUT_COMMANDS = [
    (["attack", "eval", "--signs", "clean", "--drives", "0"], locked_output),
    (["attack", "sweep", "--method", "chen", "--budgets", "0.1", "--steps", "1"], locked_output),
    (["detector", "eval", "--data", "{tmp}/no_data"], locked_output),
    (["detector", "make-data", "--train", "1", "--val", "1"], locked_sibling),
]


@pytest.mark.parametrize("argv, hold", HELD_OUTPUT_COMMANDS, ids=lambda v: " ".join(v[:2]) if isinstance(v, list) else "")
def test_a_command_whose_output_another_holds_is_one_line_exit_2(tmp_path, capsys, argv, hold):
    out = tmp_path / "out"
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    with hold(out, "avsim first --out OUT"):
        assert cli.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "in use by pid" in err and "first --out OUT" in err, err


def _hold_and_wait(folder: str, ready) -> None:
    with locked_output(folder, "a process about to be killed"):
        ready.set()
        time.sleep(60)


def test_the_lock_of_a_killed_process_is_taken_over(tmp_path):
    context = multiprocessing.get_context("spawn")
    ready = context.Event()
    holder = context.Process(target=_hold_and_wait, args=(str(tmp_path / "out"), ready))
    holder.start()
    assert ready.wait(60)
    with pytest.raises(OutputError, match="in use by pid"):
        with locked_output(tmp_path / "out", "while it lives"):
            pass
    os.kill(holder.pid, signal.SIGKILL)  # no clean-up: the lock file stays, naming a dead pid
    holder.join()
    assert (tmp_path / "out" / LOCK_NAME).exists()
    with locked_output(tmp_path / "out", "after it died") as folder:
        assert f"pid {os.getpid()}" in (folder / LOCK_NAME).read_text()


def test_a_folder_made_for_a_start_that_failed_is_removed(tmp_path):
    with pytest.raises(RuntimeError):
        with locked_output(tmp_path / "new", "a failing start", results_name="results.jsonl"):
            raise RuntimeError("the cluster cannot be reached")
    assert not (tmp_path / "new").exists()
    # A folder that was there before, or that holds a finished run, stays.
    (tmp_path / "old").mkdir()
    with pytest.raises(RuntimeError):
        with locked_output(tmp_path / "old", "a failing start", results_name="results.jsonl"):
            raise RuntimeError
    assert (tmp_path / "old").is_dir()
    with pytest.raises(RuntimeError):
        with locked_output(tmp_path / "kept", "a failing batch", results_name="results.jsonl") as folder:
            (folder / "results.jsonl").write_text("{}\n")
            raise RuntimeError
    assert (tmp_path / "kept" / "results.jsonl").exists() and not (tmp_path / "kept" / LOCK_NAME).exists()


@pytest.mark.slow  # about 20 s: one smoke sweep, with a second started into its folder
def test_a_second_sweep_into_the_same_folder_is_refused_and_the_first_finishes_intact(tmp_path):
    out = tmp_path / "out"
    # --batch 1: runs one after another, so the first sweep is still running when the second starts
    # (in lock-step all four runs would end together).
    argv = [sys.executable, "-m", "avsim", "sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--batch", "1",
            "--no-progress"]
    first = subprocess.Popen(argv, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not (out / "results.jsonl").exists():  # the first holds the folder and has begun its runs
        assert first.poll() is None and time.monotonic() < deadline, first.stderr.read().decode()
        time.sleep(0.05)
    second = subprocess.run([*argv, "--resume"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert second.returncode == 2 and len(second.stderr.splitlines()) == 1, second.stderr
    assert "in use by pid" in second.stderr and str(first.pid) in second.stderr
    assert first.wait(timeout=300) == 0, first.stderr.read().decode()
    records = read_records(out / "results.jsonl")
    assert len(records) == 4 and all(r["status"] == "ok" for r in records)
    assert len({r["spec_hash"] for r in records}) == 4
    assert not (out / LOCK_NAME).exists()


@pytest.mark.slow  # about 12 s: Ray's import and the 10 s connect timeout
def test_an_address_that_answers_but_is_no_ray_cluster_is_one_line_within_seconds(tmp_path, capsys):
    pytest.importorskip("ray")
    import socket

    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)  # accepts connections and says nothing, as a non-Ray service would to Ray
    try:
        started = time.monotonic()
        code = cli.main(["sweep", str(SMOKE), "--backend", "ray", "--address", f"127.0.0.1:{listener.getsockname()[1]}",
                         "--out", str(tmp_path / "out"), "--no-progress"])
        elapsed_s = time.monotonic() - started
    finally:
        listener.close()
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "no Ray cluster answers" in err, err
    assert elapsed_s < 30
    assert not (tmp_path / "out").exists()


def test_what_is_in_the_place_of_an_output_is_named_in_one_line(tmp_path):
    (tmp_path / "rrd").write_text("")
    (tmp_path / "summary.md").mkdir()
    os.mkfifo(tmp_path / "results.jsonl")
    os.mkfifo(tmp_path / "plots")
    cases = [(["rrd/run.rrd"], [], "rrd is a file, where this command makes a folder"),
             ([], ["plots"], r"plots is a pipe \(FIFO\), where this command makes a folder"),
             (["summary.md"], [], "summary.md is a folder, where this command writes a file"),
             (["results.jsonl"], [], r"results.jsonl is a pipe \(FIFO\), not a regular file, where this command")]
    for files, folders, match in cases:
        with pytest.raises(OutputError, match=match) as refused:
            check_writable(tmp_path, files, folders)
        assert "\n" not in str(refused.value)
    check_writable(tmp_path, ["new/run.rrd"], ["new_folder"])  # what is missing passes: it will be made
