"""`avsim detector train | eval` refuse bad datasets and flags through `avsim.cli.main`: exit 2,
one line on stderr naming the file, line and field, and no output written, before any training
or scoring."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from avsim import cli
from avsim.perception.detector import train as train_module

GOOD = {"image": "images/a.png", "boxes": [[8, 8, 24, 24]], "classes": ["stop_sign"],
        "meta": {"camera": "front", "target_kind": "stop_sign", "dist_m": 30.0}}


def _dataset(root: Path, bad_line: dict) -> Path:
    """A dataset of one 64x64 PNG whose train.jsonl and val.jsonl hold a good line, then `bad_line`."""
    (root / "images").mkdir(parents=True)
    cv2.imwrite(str(root / "images" / "a.png"), np.zeros((64, 64, 3), np.uint8))
    for split in ("train", "val"):
        (root / f"{split}.jsonl").write_text(json.dumps(GOOD) + "\n" + json.dumps(bad_line) + "\n")
    return root


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a training step runs or an image is scored."""
    def _boom(*args, **kwargs):
        raise AssertionError("the command started work before refusing its input")

    monkeypatch.setattr(train_module, "compute_loss", _boom)
    monkeypatch.setattr("avsim.perception.detector.infer.SignDetectorRunner.detect", _boom)


def _refused(argv: list[str], capsys) -> str:
    try:
        status = cli.main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


# The audit's lines: internal errors (exit 1), the meta ones in eval only after earlier images were scored.
BAD_LINES = {
    "image 5": ({**GOOD, "image": 5}, "field 'image'"),
    "nested classes": ({**GOOD, "classes": [["stop_sign"]]}, "field 'classes'"),
    "boxes and classes 5": ({**GOOD, "boxes": 5, "classes": 5}, "field 'boxes'"),
    "no target_kind": ({**GOOD, "meta": {"camera": "front", "dist_m": 30.0}}, "field 'meta.target_kind'"),
    "dist_m far": ({**GOOD, "meta": {**GOOD["meta"], "dist_m": "far"}}, "field 'meta.dist_m'"),
    "a missing image": ({**GOOD, "image": "images/gone.png"}, "does not exist"),
}
EVAL_ONLY = ("no target_kind", "dist_m far")  # meta is read by evaluation; training ignores it


@pytest.mark.parametrize("command, name", [(command, name) for command in ("train", "eval") for name in BAD_LINES
                                           if command == "eval" or name not in EVAL_ONLY])
def test_a_bad_label_line_is_one_line_naming_file_line_and_field(tmp_path, capsys, no_work, command, name):
    bad_line, mention = BAD_LINES[name]
    data = _dataset(tmp_path / "d", bad_line)
    out = tmp_path / ("w.pt" if command == "train" else "ev")
    argv = (["detector", "train", "--data", str(data), "--out", str(out), "--input-size", "64x64"] if command == "train"
            else ["detector", "eval", "--data", str(data), "--out", str(out), "--no-progress"])
    line = _refused(argv, capsys)
    split = "train" if command == "train" else "val"
    assert f"{split}.jsonl:2" in line and mention in line
    assert not out.exists()


def test_train_input_size_has_an_upper_bound(tmp_path, capsys):
    line = _refused(["detector", "train", "--data", str(tmp_path), "--out", str(tmp_path / "w.pt"),
                     "--input-size", "64000x64000"], capsys)
    assert "--input-size" in line and "4096" in line


def test_train_refuses_an_existing_out_without_resume_or_overwrite(tmp_path, capsys, no_work):
    data = _dataset(tmp_path / "d", GOOD)
    out = tmp_path / "w.pt"
    out.write_bytes(b"someone's file")
    line = _refused(["detector", "train", "--data", str(data), "--out", str(out), "--input-size", "64x64"], capsys)
    assert "already exists" in line and "--resume" in line and "--overwrite" in line
    assert out.read_bytes() == b"someone's file"
