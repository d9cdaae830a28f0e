"""The shared output-path checks, temporary names and checked image writes (`avsim.outputs`)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from avsim.errors import OutputError
from avsim.outputs import (check_output_file, check_output_folder, check_output_prefix, remove_stale_temporaries,
                           temporary_path, write_bytes_atomic, write_image)


def test_a_file_in_a_missing_folder_is_fine_and_the_check_creates_nothing(tmp_path):
    check_output_file(tmp_path / "new" / "deeper" / "out.json", "--json")
    check_output_folder(tmp_path / "new" / "results", "--out")
    assert list(tmp_path.iterdir()) == []  # the probe file is gone, no folder was made


@pytest.mark.parametrize("name, fix", [("", "needs a file name"), ("  ", "needs a file name"), (".", "names a folder"),
                                       ("sub/", "names a folder")])
def test_names_that_are_no_file(tmp_path, name, fix):
    with pytest.raises(OutputError, match=fix):
        check_output_file(name, "--json")


def test_an_existing_file_may_be_replaced_but_not_a_folder_or_a_device(tmp_path):
    (tmp_path / "old.json").write_text("{}")
    check_output_file(tmp_path / "old.json", "--json")
    with pytest.raises(OutputError, match="is a folder"):
        check_output_file(tmp_path, "--json")
    with pytest.raises(OutputError, match="'/dev/null' is a device, not a regular file; give another path"):
        check_output_file("/dev/null", "--json")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output_folder(tmp_path / "old.json", "--out")


def test_a_prefix_checks_each_file_it_names(tmp_path):
    (tmp_path / "shot_side.png").mkdir()
    with pytest.raises(OutputError, match="shot_side.png' is a folder"):
        check_output_prefix(str(tmp_path / "shot"), "--out", ("_front.png", "_side.png"))
    with pytest.raises(OutputError, match="prefix"):
        check_output_prefix(str(tmp_path) + "/", "--out", ("_front.png",))


def test_places_where_no_file_can_be_made(tmp_path):
    for path in ("/proc/x.json", "/sys/x.json"):
        with pytest.raises(OutputError, match="cannot write in"):
            check_output_file(path, "--json")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(OutputError, match="afile is a file"):
        check_output_file(tmp_path / "afile" / "sub" / "x.json", "--json")


def test_a_dead_writers_temporaries_are_removed_and_a_live_ones_kept(tmp_path):
    target = tmp_path / "a.rrd"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(dead.stdout)  # a process that has exited
    mine = temporary_path(target)  # this (live) process's
    mine.write_text("in progress")
    theirs = mine.with_name(mine.name.replace(f".{os.getpid()}@", f".{dead_pid}@"))
    theirs.write_text("left by a kill")
    other_output = tmp_path / f".a.rrd.x.{dead_pid}@{mine.name.split('@')[1]}"  # another file's, never touched
    other_output.write_text("not ours")
    assert remove_stale_temporaries(target) == [theirs]
    assert mine.exists() and other_output.exists() and not theirs.exists()


def test_write_image_names_the_file_when_nothing_can_be_written(tmp_path):
    image = np.zeros((8, 8, 3), np.uint8)
    write_image(tmp_path / "ok.png", image)
    assert (tmp_path / "ok.png").stat().st_size > 0
    with pytest.raises(OutputError, match="x.nosuchformat"):
        write_image(tmp_path / "x.nosuchformat", image)
    with pytest.raises(OutputError, match="/proc/x.png"):
        write_image("/proc/x.png", image)
    with pytest.raises(OutputError, match="adir"):
        (tmp_path / "adir").mkdir()
        write_bytes_atomic(tmp_path / "adir", b"x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "ok.png"]  # no temporary file left


@pytest.mark.parametrize("argv", [["sweep", "{input}", "--out", "{tmp}/o"], ["run", "--config", "{input}"],
                                  ["reproduce", "--experiments", "{input}", "--out", "{tmp}/o"]])
def test_an_input_that_is_a_device_or_a_pipe_is_refused_before_it_is_read(tmp_path, capsys, argv):
    from avsim import cli

    pipe = tmp_path / "plan.toml"
    os.mkfifo(pipe)  # read, it would block with no writer; /dev/zero would be read until memory ran out
    for source, kind in (("/dev/zero", "a device"), (str(pipe), "a pipe (FIFO)")):
        code = cli.main([arg.replace("{input}", source).replace("{tmp}", str(tmp_path)) for arg in argv])
        err = capsys.readouterr().err.splitlines()
        assert code == 2 and len(err) == 1 and f"is {kind}, not a regular file" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.toml"]


def test_a_symbolic_link_as_an_output_file_is_refused_rather_than_replaced(tmp_path):
    (tmp_path / "real.json").write_text("{}")
    for name, target in (("link.json", tmp_path / "real.json"), ("dangling.json", tmp_path / "no" / "x.json")):
        (tmp_path / name).symlink_to(target)
        with pytest.raises(OutputError, match="is a symbolic link"):
            check_output_file(tmp_path / name, "--json")
        assert (tmp_path / name).is_symlink()


def test_a_folder_holding_a_file_the_command_writes_last_is_refused_naming_each(tmp_path):
    from avsim.outputs import refuse_earlier_outputs

    refuse_earlier_outputs(tmp_path / "new", ("report.md",))
    (tmp_path / "report.md").write_text("mine")
    (tmp_path / "notes.txt").write_text("kept")
    with pytest.raises(OutputError, match=r"already holds report.md, which this run would replace"):
        refuse_earlier_outputs(tmp_path, ("frames.jsonl", "report.md"))
