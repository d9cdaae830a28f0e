"""The network built from a cfg: YOLOv3-tiny's shape, a v4-tiny-style cfg, and refused cfgs."""

import numpy as np
import pytest
import torch

from avsim.perception.yolo.cfg import DarknetFileError, parse_cfg, parse_cfg_text
from avsim.perception.yolo.fetch import model_paths
from avsim.perception.yolo.layers import Convolutional
from avsim.perception.yolo.network import DarknetNetwork
from tests.perception.yolo.darknet_files import TINY_CFG


def test_yolov3_tiny_builds_two_heads_at_strides_32_and_16():
    network = DarknetNetwork(parse_cfg(model_paths()[0]))
    assert network.input_size_px == (416, 416) and network.size_multiple_px == 32
    assert [h.anchors_px.tolist() for h in network.heads] == [[[81, 82], [135, 169], [344, 319]],
                                                              [[10, 14], [23, 27], [37, 58]]]
    with torch.no_grad():
        maps = network(torch.zeros(1, 3, 512, 704))
    assert [tuple(m.shape) for m in maps] == [(1, 255, 16, 22), (1, 255, 32, 44)]
    convs = [layer for layer in network.layers if isinstance(layer, Convolutional)]
    assert len(convs) == 13 and sum(c.batch_normalize for c in convs) == 11


def test_a_v4_tiny_style_cfg_with_groups_shortcut_and_scale_x_y_builds_and_runs():
    network = DarknetNetwork(parse_cfg_text(TINY_CFG))
    assert network.heads[0].scale_x_y == 1.05 and network.heads[0].anchors_px.shape == (3, 2)
    maps = network(torch.rand(2, 3, 64, 96, requires_grad=True))
    assert [tuple(m.shape) for m in maps] == [(2, 21, 16, 24), (2, 14, 32, 48)]


@pytest.mark.parametrize("edit, message", [
    (("[maxpool]\nsize=2\nstride=2\n", "[reorg]\nstride=2\n"), r"layer type \[reorg\] is not supported"),
    (("layers = -3", "layers = 10"), "refers to layer 10, which is not an earlier layer"),
    (("filters=14", "filters=15"), r"15 channels, but 2 anchors x \(5 \+ 2 classes\) need 14"),
    (("mask = 0,1", "mask = 0,7"), r"mask \[0, 7\] names anchors that do not exist"),
    (("activation=mish", "activation=selu"), "activation 'selu' is not supported"),
    (("scale_x_y = 1.05", "new_coords=1"), "new_coords=1"),
])
def test_unsupported_or_inconsistent_cfgs_are_refused_naming_the_layer(edit, message):
    old, new = edit
    assert old in TINY_CFG
    with pytest.raises(DarknetFileError, match=message):
        DarknetNetwork(parse_cfg_text(TINY_CFG.replace(old, new, 1), "user.cfg"))


def test_a_cfg_without_yolo_heads_is_refused():
    with pytest.raises(DarknetFileError, match="no \\[yolo\\] layer"):
        DarknetNetwork(parse_cfg_text("[net]\n[convolutional]\nfilters=4\nsize=1\n"))


def test_network_is_differentiable_from_pixels():
    network = DarknetNetwork(parse_cfg_text(TINY_CFG))
    for p in network.parameters():
        torch.nn.init.normal_(p, 0, 0.2)
    x = torch.rand(1, 3, 64, 64, requires_grad=True)
    sum(m.square().sum() for m in network(x)).backward()
    assert x.grad is not None and np.isfinite(x.grad.numpy()).all() and x.grad.abs().sum() > 0
