"""Training: a smoke run on synthetic renders, bit-exact resume, divergence stop, and the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from avsim.perception.detector import train as train_module
from avsim.perception.detector.data import DatasetError
from avsim.perception.detector.train import TrainingError, lr_at, main, train
from avsim.perception.detector.weights import load_weights

SMALL_INPUT = (320, 256)


@pytest.fixture(scope="module")
def smoke_run(synthetic_dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("smoke") / "detector.pt"
    # At half the deployed input size, as the other training tests: a quarter of the pixels to learn from, and the
    # same code paths (the input size is the weights' meta, which loading checks).
    result = train(synthetic_dataset, out, epochs=3, batch_size=8, lr=2e-3, seed=0, input_size=SMALL_INPUT, log_every=0,
                   progress=False)
    return out, result


def test_smoke_training_lowers_the_loss_and_writes_loadable_weights(smoke_run):
    out, result = smoke_run
    history = result["history"]
    assert [h["epoch"] for h in history] == [1, 2, 3]
    assert history[-1]["total"] < history[0]["total"]
    assert all(math.isfinite(h[k]) for h in history for k in ("obj", "cls", "box", "total"))
    assert set(history[-1]["map50"]) == {"stop_sign", "yield", "speed_limit"}
    # Each epoch says where its arithmetic ran, since another CPU or thread count gives other weights.
    assert all(h["ran_on"] == train_module.ran_on("cpu") for h in history)
    assert history[0]["ran_on"]["torch_threads"] == torch.get_num_threads()
    assert history[0]["ran_on"]["cpu_capability"] == torch.backends.cpu.get_cpu_capability()
    raw = torch.load(out, weights_only=True, map_location="cpu")
    assert raw["epoch"] == 3 and raw["meta"]["input_size"] == list(SMALL_INPUT) and raw["meta"]["seed"] == 0
    model, meta = load_weights(out)
    assert meta["class_names"] == ["stop_sign", "yield", "speed_limit"]
    with torch.no_grad():
        assert len(model(torch.rand(1, 3, SMALL_INPUT[1], SMALL_INPUT[0]))) == 2


def _interrupt_after_first_checkpoint(monkeypatch):
    real = train_module.save_checkpoint
    calls = []

    def save_then_die(*args, **kwargs):
        real(*args, **kwargs)
        calls.append(1)
        if len(calls) == 1:
            raise KeyboardInterrupt  # killed right after the epoch-1 checkpoint

    monkeypatch.setattr(train_module, "save_checkpoint", save_then_die)


def test_resume_after_epoch_one_matches_an_uninterrupted_run(synthetic_dataset, tmp_path, monkeypatch, capsys):
    kwargs = dict(epochs=2, batch_size=8, lr=2e-3, seed=5, input_size=SMALL_INPUT, log_every=0, progress=False)
    straight = tmp_path / "straight.pt"
    train(synthetic_dataset, straight, **kwargs)

    resumed = tmp_path / "resumed.pt"
    with monkeypatch.context() as patch:
        _interrupt_after_first_checkpoint(patch)
        with pytest.raises(KeyboardInterrupt):
            train(synthetic_dataset, resumed, **kwargs)
    assert torch.load(resumed, weights_only=True)["epoch"] == 1
    result = train(synthetic_dataset, resumed, resume=True, **kwargs)
    assert [h["epoch"] for h in result["history"]] == [1, 2]
    assert "will not equal" not in capsys.readouterr().out  # the same arithmetic: no note

    a = torch.load(straight, weights_only=True)
    b = torch.load(resumed, weights_only=True)
    for key in ("model",):
        assert a[key].keys() == b[key].keys()
        for name in a[key]:
            assert torch.equal(a[key][name], b[key][name]), name
    for name, value in a["train_state"]["raw_model"].items():
        assert torch.equal(value, b["train_state"]["raw_model"][name]), name
    assert a["train_state"]["step"] == b["train_state"]["step"]


def test_resume_on_other_arithmetic_says_the_weights_will_differ(synthetic_dataset, tmp_path, monkeypatch, capsys):
    kwargs = dict(epochs=2, batch_size=16, seed=0, input_size=SMALL_INPUT, log_every=0, progress=False)
    out = tmp_path / "w.pt"
    with monkeypatch.context() as patch:
        _interrupt_after_first_checkpoint(patch)
        with pytest.raises(KeyboardInterrupt):
            train(synthetic_dataset, out, **kwargs)
    real = train_module.ran_on
    monkeypatch.setattr(train_module, "ran_on", lambda device: {**real(device), "torch_threads": 97})
    capsys.readouterr()
    result = train(synthetic_dataset, out, resume=True, **kwargs)
    assert "will not equal an uninterrupted run's bit for bit" in capsys.readouterr().out
    assert [h["ran_on"]["torch_threads"] for h in result["history"]] == [torch.get_num_threads(), 97]


def test_resume_refuses_different_settings(synthetic_dataset, tmp_path):
    out = tmp_path / "w.pt"
    train(synthetic_dataset, out, epochs=1, batch_size=16, seed=0, input_size=SMALL_INPUT, log_every=0, progress=False)
    with pytest.raises(Exception, match="trained with seed=0, not 1"):
        train(synthetic_dataset, out, epochs=1, batch_size=16, seed=1, resume=True, input_size=SMALL_INPUT, progress=False)


def test_non_finite_loss_stops_with_the_term_and_step(synthetic_dataset, tmp_path, monkeypatch):
    real = train_module.compute_loss

    def poisoned(outputs, targets, **kwargs):
        losses = real(outputs, targets, **kwargs)
        losses["box"] = losses["box"] * float("nan")
        return losses

    monkeypatch.setattr(train_module, "compute_loss", poisoned)
    with pytest.raises(TrainingError, match=r"loss term 'box' became nan at epoch 1 step 1"):
        train(synthetic_dataset, tmp_path / "w.pt", epochs=1, batch_size=16, input_size=SMALL_INPUT, progress=False)
    assert not (tmp_path / "w.pt").exists()


def test_lr_schedule_warms_up_then_decays():
    lrs = [lr_at(s, 100, 1e-3, 10, 0.05) for s in range(100)]
    assert lrs[0] == pytest.approx(1e-4) and lrs[9] == pytest.approx(1e-3)
    assert all(a >= b for a, b in zip(lrs[9:], lrs[10:]))
    assert lrs[-1] == pytest.approx(5e-5, rel=0.05)


def test_cli_trains_and_reports_bad_input_in_one_line(synthetic_dataset, tmp_path, capsys):
    out = tmp_path / "cli.pt"
    args = ["--data", str(synthetic_dataset), "--out", str(out), "--epochs", "1", "--seed", "0",
            "--batch-size", "16", "--input-size", "320x256", "--log-every", "0", "--no-progress"]
    assert main(args) == 0
    assert out.is_file()
    assert main(args + ["--resume"]) == 0  # already complete: nothing to do
    assert main(["--data", str(tmp_path / "nowhere"), "--out", str(out), "--epochs", "1", "--seed", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "avsim detector make-data --out" in err[0]


@pytest.mark.parametrize("size", ["300x200", "64000x64000", "4128x480", "0x480", "640"])
def test_input_size_is_refused_by_argparse_in_one_line(tmp_path, capsys, size):
    # 64000x64000 passed the multiple-of-32 check and ended in an OpenCV out-of-memory error.
    with pytest.raises(SystemExit) as info:
        main(["--data", str(tmp_path), "--out", str(tmp_path / "w.pt"), "--input-size", size])
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and "--input-size" in err[0]
    assert "multiple of 32 in [32, 4096]" in err[0] or "expects WxH" in err[0]


def _tiny_dataset(root: Path, val_images: tuple[str, ...] = ("v.png",)) -> Path:
    """One 64x64 training image and the validation lines `val_images` (only v.png is written)."""
    (root / "images").mkdir(parents=True)
    for name in ("t.png", "v.png"):
        cv2.imwrite(str(root / "images" / name), np.zeros((64, 64, 3), np.uint8))
    line = lambda name: json.dumps({"image": f"images/{name}", "boxes": [[8, 8, 24, 24]], "classes": ["yield"]}) + "\n"
    (root / "train.jsonl").write_text(line("t.png"))
    (root / "val.jsonl").write_text("".join(line(name) for name in val_images))
    return root


@pytest.fixture
def no_training(monkeypatch):
    """Fail the test if a training step runs."""
    def _boom(*args, **kwargs):
        raise AssertionError("training started before the bad input was refused")

    monkeypatch.setattr(train_module, "compute_loss", _boom)


def test_a_missing_validation_image_is_refused_before_the_first_epoch(tmp_path, no_training):
    # It used to be found at validation, after a whole epoch of training.
    data = _tiny_dataset(tmp_path / "d", val_images=("v.png", "gone.png"))
    with pytest.raises(DatasetError, match=r"val.jsonl:2: image .*gone.png does not exist"):
        train(data, tmp_path / "w.pt", epochs=1, input_size=(64, 64), progress=False)
    assert not (tmp_path / "w.pt").exists()


def test_an_existing_out_is_refused_without_resume_or_overwrite(tmp_path, capsys, monkeypatch):
    data = _tiny_dataset(tmp_path / "d")
    out = tmp_path / "w.pt"
    out.write_text("a user's file")
    args = ["--data", str(data), "--out", str(out), "--epochs", "1", "--input-size", "64x64", "--width-mult", "0.125",
            "--log-every", "0", "--no-progress"]
    with monkeypatch.context() as patch:
        patch.setattr(train_module, "compute_loss", lambda *a, **k: pytest.fail("trained over an existing --out"))
        assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already exists" in err[0] and "--resume" in err[0] and "--overwrite" in err[0]
    assert out.read_text() == "a user's file"
    assert main(args + ["--overwrite"]) == 0  # said explicitly: replaced by a checkpoint
    assert torch.load(out, weights_only=True)["epoch"] == 1
    with pytest.raises(SystemExit):  # continue it or replace it, not both
        main(args + ["--overwrite", "--resume"])
