"""Darknet .weights: both header layouts, batch norm folded as Darknet computes it, size checks."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from avsim.perception.yolo.cfg import DarknetFileError, parse_cfg_text
from avsim.perception.yolo.fetch import model_paths
from avsim.perception.yolo.layers import LEAKY_SLOPE, Convolutional
from avsim.perception.yolo.network import DarknetNetwork
from avsim.perception.yolo.weights import load_weights, read_header
from tests.perception.yolo.darknet_files import TINY_CFG, write_weights


def test_the_fetched_weights_have_a_64_bit_seen_and_exactly_fill_the_cfg():
    cfg, weights, _ = model_paths()
    header = load_weights(DarknetNetwork(parse_cfg_text(cfg.read_text())), weights)
    assert (header.major, header.minor, header.revision, header.size_bytes) == (0, 2, 0, 20)
    assert header.seen == 32_013_312


@pytest.mark.parametrize("version, header_bytes", [((0, 2, 0), 20), ((0, 1, 0), 16), ((1, 0, 0), 20)])
def test_conv_layers_compute_darknet_batch_norm_with_either_header(tmp_path, version, header_bytes):
    network = DarknetNetwork(parse_cfg_text(TINY_CFG))
    path = tmp_path / "tiny.weights"
    arrays = write_weights(path, network, np.random.default_rng(1), version)
    header = load_weights(network, path)
    assert header.size_bytes == header_bytes and header.seen == 12345
    first, record = network.layers[0], arrays[0]
    x = torch.rand(1, 3, 16, 16, dtype=torch.float64)
    conv = F.conv2d(x, torch.from_numpy(record["kernel"]).double(), stride=2, padding=1)
    mean, var, scale, bias = (torch.from_numpy(record[k]).double().view(1, -1, 1, 1) for k in ("mean", "var", "scale", "bias"))
    expected = F.leaky_relu((conv - mean) / (var.sqrt() + 1e-6) * scale + bias, LEAKY_SLOPE)
    with torch.no_grad():
        assert torch.allclose(first(x.float()).double(), expected, atol=1e-5)
    plain = [layer for layer in network.layers if isinstance(layer, Convolutional) and not layer.batch_normalize][0]
    assert torch.equal(plain.conv.bias, torch.from_numpy(arrays[2]["bias"]))


@pytest.mark.parametrize("extra_floats", [-1, 1])
def test_weights_that_do_not_fit_the_cfg_are_refused(tmp_path, extra_floats):
    network = DarknetNetwork(parse_cfg_text(TINY_CFG))
    path = tmp_path / "tiny.weights"
    write_weights(path, network, np.random.default_rng(1), extra_floats=max(extra_floats, 0))
    if extra_floats < 0:
        path.write_bytes(path.read_bytes()[:-4])
    with pytest.raises(DarknetFileError, match="the weights are not for this cfg"):
        load_weights(network, path)


def test_truncated_transposed_and_absent_files_are_refused(tmp_path):
    with pytest.raises(DarknetFileError, match="shorter than the header"):
        read_header(b"\0" * 8, "x.weights")
    with pytest.raises(DarknetFileError, match="transposed"):
        read_header(np.array([1001, 0, 0, 0, 0], "<i4").tobytes(), "x.weights")
    with pytest.raises(DarknetFileError, match="do not exist; check perception.yolo_weights"):
        load_weights(DarknetNetwork(parse_cfg_text(TINY_CFG)), tmp_path / "absent.weights")
