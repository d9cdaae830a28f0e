"""Checkpoint files: weights-only round trip, atomic writes, and one-line errors for bad files."""

from __future__ import annotations

import os

import pytest
import torch

from avsim.errors import AvsimError
from avsim.perception.detector.model import build_detector
from avsim.perception.detector.weights import WeightsError, load_weights, save_checkpoint, training_sentence

META = {"arch": {"width_mult": 0.5, "depth": 1, "num_classes": 3, "act": "leaky_relu"}, "input_size": [320, 256],
        "class_names": ["stop_sign", "yield", "speed_limit"], "seed": 0, "epochs": 1}


def _model(width_mult: float = 0.5) -> torch.nn.Module:
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(1)
        return build_detector(width_mult=width_mult)


def test_round_trip_is_weights_only_and_atomic(tmp_path):
    model = _model()
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-3)
    path = save_checkpoint(tmp_path / "sub" / "w.pt", model, optimizer, 1, META, {"step": 3, "history": [{"total": 1.5}]})
    assert sorted(os.listdir(path.parent)) == ["w.pt"]  # no temporary file left behind
    raw = torch.load(path, weights_only=True, map_location="cpu")
    assert raw["meta"] == META and raw["train_state"]["step"] == 3
    loaded, meta = load_weights(path)
    assert meta == META and not loaded.training
    x = torch.rand(1, 3, 64, 96)
    with torch.no_grad():
        for a, b in zip(model.eval()(x), loaded(x)):
            assert torch.equal(a, b)


def _assert_one_line(exc: AvsimError, *fragments: str) -> None:
    text = str(exc)
    assert "\n" not in text and len(text) < 400
    for fragment in fragments:
        assert fragment in text


def test_missing_file(tmp_path):
    with pytest.raises(WeightsError) as info:
        load_weights(tmp_path / "nope.pt")
    _assert_one_line(info.value, "missing", "avsim detector train")
    assert isinstance(info.value, AvsimError)


def test_a_folder_is_named_as_one_not_as_missing(tmp_path):
    with pytest.raises(WeightsError) as info:
        load_weights(tmp_path)
    _assert_one_line(info.value, "is a folder", "sign_detector.pt")


@pytest.mark.parametrize("content", [os.urandom(2048), b"", b"hello\nworld\n"])
def test_garbage_bytes(tmp_path, content):
    path = tmp_path / "w.pt"
    path.write_bytes(content)
    with pytest.raises(WeightsError) as info:
        load_weights(path)
    _assert_one_line(info.value, "corrupt", "avsim detector train")


def test_valid_torch_file_with_wrong_content(tmp_path):
    path = tmp_path / "w.pt"
    torch.save({"foo": torch.zeros(3)}, path)
    with pytest.raises(WeightsError) as info:
        load_weights(path)
    _assert_one_line(info.value, "not avsim detector weights", "avsim detector train")
    torch.save(_model().state_dict(), path)  # a bare state_dict
    with pytest.raises(WeightsError):
        load_weights(path)


def test_weights_that_do_not_fit_the_architecture(tmp_path):
    path = save_checkpoint(tmp_path / "w.pt", _model(1.0), None, 1, META)  # meta says width 0.5
    with pytest.raises(WeightsError) as info:
        load_weights(path)
    _assert_one_line(info.value, "architecture does not match", "avsim detector train")


def test_refuses_to_write_values_that_would_not_load_weights_only(tmp_path):
    with pytest.raises(TypeError, match=r"checkpoint\['meta'\]\['version'\] is a TorchVersion"):
        save_checkpoint(tmp_path / "w.pt", _model(), None, 1, {**META, "version": torch.__version__})
    assert not (tmp_path / "w.pt").exists()


def test_export_keeps_the_weights_and_drops_the_training_state(tmp_path):
    from avsim.perception.detector.weights import export_weights

    model = _model()
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-3)
    checkpoint = save_checkpoint(tmp_path / "ckpt.pt", model, optimizer, 4, META, {"step": 3, "history": []})
    deployed = export_weights(checkpoint, tmp_path / "deploy.pt")
    raw = torch.load(deployed, weights_only=True, map_location="cpu")
    assert raw["optimizer"] is None and raw["train_state"] == {} and raw["epoch"] == 4 and raw["meta"] == META
    loaded, _ = load_weights(deployed)
    x = torch.rand(1, 3, 64, 96)
    with torch.no_grad():
        for a, b in zip(model.eval()(x), loaded(x)):
            assert torch.equal(a, b)


@pytest.mark.parametrize("file_name, data_dir", [("sign_detector_scenes.pt", "data/signs_all"),
                                                  ("sign_detector_windows.pt", "data/signs_windows")])
def test_the_retrained_weights_load_beside_the_shipped_ones_and_differ(file_name, data_dir):
    """The same network retrained on other renders (docs/realism_networks.md): sign_detector_scenes.pt under
    every scene setting, sign_detector_windows.pt under window_geometry."""
    from avsim.perception.detector.weights import SHIPPED_WEIGHTS

    shipped, shipped_meta = load_weights(SHIPPED_WEIGHTS)
    retrained, retrained_meta = load_weights(SHIPPED_WEIGHTS.with_name(file_name))
    assert retrained_meta["arch"] == shipped_meta["arch"] and retrained_meta["input_size"] == shipped_meta["input_size"]
    assert retrained_meta["data_dir"] == data_dir and retrained_meta["epochs"] == 6
    shipped_tensors = shipped.state_dict()
    differ = [name for name, tensor in retrained.state_dict().items() if not torch.equal(tensor, shipped_tensors[name])]
    assert len(differ) > 10


def test_a_device_or_a_pipe_as_weights_is_refused_without_reading_it(tmp_path):
    pipe = tmp_path / "w.pt"
    os.mkfifo(pipe)
    for path, kind in (("/dev/zero", "a device"), (pipe, r"a pipe \(FIFO\)")):
        with pytest.raises(WeightsError, match=f"is {kind}, not a regular file"):
            load_weights(path)


HERE = {"cpu": "AMD EPYC 9B14", "cpu_capability": "AVX512", "onednn_max_cpu_isa": "unset", "torch_threads": 2,
        "device": "cpu"}


def test_the_training_sentence_names_where_each_epoch_ran():
    meta = {**META, "seed": 1, "train_images": 6000, "data_dir": "data/signs",
            "history": [{"epoch": 1, "ran_on": HERE}, {"epoch": 2, "ran_on": HERE}]}
    assert training_sentence(meta) == ("Trained for 2 epochs with seed 1 on 6000 images of data/signs, on AMD EPYC 9B14 "
                                       "(AVX512 kernels, oneDNN cap unset, 2 threads).")
    resumed = {**meta, "history": [{"epoch": 1, "ran_on": HERE}, {"epoch": 2, "ran_on": {**HERE, "torch_threads": 1}}]}
    assert training_sentence(resumed).endswith("2 threads), then on AMD EPYC 9B14 (AVX512 kernels, oneDNN cap unset, "
                                               "1 thread).")
    back = {**meta, "history": [*resumed["history"], {"epoch": 3, "ran_on": HERE}]}
    assert training_sentence(back).endswith("1 thread), then on AMD EPYC 9B14 (AVX512 kernels, oneDNN cap unset, "
                                            "2 threads).")


@pytest.mark.parametrize("history", [None, [], [{"epoch": 1}], [{"epoch": 1, "ran_on": HERE}, {"epoch": 2}], "bad", [3]])
def test_weights_from_before_ran_on_say_it_is_not_recorded(history):
    meta = {**META, "history": history} if history is not None else dict(META)
    sentence = training_sentence(meta)  # a malformed history is read, never raised on
    assert "is not recorded, and the same data and seed give these weights only on the same arithmetic" in sentence
