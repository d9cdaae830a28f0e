"""Training: a smoke run on synthetic renders, bit-exact resume, divergence stop, and the CLI."""

from __future__ import annotations

import math

import pytest
import torch

from avsim.perception.detector import train as train_module
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


def test_resume_after_epoch_one_matches_an_uninterrupted_run(synthetic_dataset, tmp_path, monkeypatch):
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

    a = torch.load(straight, weights_only=True)
    b = torch.load(resumed, weights_only=True)
    for key in ("model",):
        assert a[key].keys() == b[key].keys()
        for name in a[key]:
            assert torch.equal(a[key][name], b[key][name]), name
    for name, value in a["train_state"]["raw_model"].items():
        assert torch.equal(value, b["train_state"]["raw_model"][name]), name
    assert a["train_state"]["step"] == b["train_state"]["step"]


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
    assert main(args[:-3] + ["--input-size", "300x200"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "avsim detector make-data --out" in err[0] and "multiples of 32" in err[1]
