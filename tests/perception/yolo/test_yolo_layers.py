"""Darknet layer semantics: the maxpool's asymmetric padding, upsample, grouped route."""

import torch
import torch.nn.functional as F

from avsim.perception.yolo.cfg import parse_cfg_text
from avsim.perception.yolo.layers import MaxPool, Route, Upsample


def _section(text: str):
    return parse_cfg_text("[net]\n" + text)[1]


def test_stride_1_maxpool_keeps_the_size_and_takes_the_cell_right_and_below():
    pool = MaxPool(_section("[maxpool]\nsize=2\nstride=1\n"))
    x = torch.randn(1, 2, 13, 13)
    y = pool(x)
    assert y.shape == x.shape
    # Padded cells never win, even over negative values: padding by repeating the edge is the same.
    edge = F.pad(x, (0, 1, 0, 1), mode="replicate")
    expected = torch.stack([edge[..., :-1, :-1], edge[..., :-1, 1:], edge[..., 1:, :-1], edge[..., 1:, 1:]]).amax(dim=0)
    assert torch.equal(y, expected)
    assert torch.equal(y[..., -1, -1], x[..., -1, -1])


def test_stride_2_maxpool_halves_even_sizes_and_rounds_odd_ones_up():
    pool = MaxPool(_section("[maxpool]\nsize=2\nstride=2\n"))
    assert pool(torch.randn(1, 1, 416, 416)).shape[-2:] == (208, 208)
    x = -torch.rand(1, 1, 13, 13) - 1.0  # all negative: a zero pad would win at the edge
    y = pool(x)
    assert y.shape[-2:] == (7, 7) and torch.equal(y[..., -1, -1], x[..., -1, -1])


def test_explicit_padding_splits_before_and_after():
    pool = MaxPool(_section("[maxpool]\nsize=3\nstride=1\npadding=2\n"))
    x = torch.randn(1, 1, 5, 5)
    assert torch.equal(pool(x), F.max_pool2d(x, 3, 1, padding=1))


def test_upsample_is_nearest_times_scale():
    up = Upsample(_section("[upsample]\nstride=2\nscale=0.5\n"))
    x = torch.arange(4.0).view(1, 1, 2, 2)
    assert torch.equal(up(x), torch.tensor([[0.0, 0, .5, .5], [0, 0, .5, .5], [1, 1, 1.5, 1.5], [1, 1, 1.5, 1.5]]).view(1, 1, 4, 4))


def test_grouped_route_takes_that_group_of_each_input():
    a, b = torch.randn(1, 4, 3, 3), torch.randn(1, 6, 3, 3)
    assert torch.equal(Route((0, 1), 2, 1)([a, b]), torch.cat([a[:, 2:], b[:, 3:]], dim=1))
    assert torch.equal(Route((0,), 1, 0)([a]), a)
