"""The network's output layout and BN folding."""

from __future__ import annotations

import torch

from avsim.perception.base import SIGN_CLASSES
from avsim.perception.detector.model import DEPLOY_INPUT_SIZE, STRIDES, build_detector, count_macs


def _seeded_model(**kwargs) -> torch.nn.Module:
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        return build_detector(**kwargs)


def test_output_shapes_per_stride():
    w_in, h_in = DEPLOY_INPUT_SIZE
    model = _seeded_model().eval()
    with torch.no_grad():
        outputs = model(torch.rand(2, 3, h_in, w_in))
    assert [tuple(o.shape) for o in outputs] == [(2, 1 + len(SIGN_CLASSES) + 4, h_in // s, w_in // s) for s in STRIDES]
    assert all(torch.isfinite(o).all() for o in outputs)


def test_model_is_small():
    model = _seeded_model()
    params = sum(p.numel() for p in model.parameters())
    assert params < 2_000_000
    assert 4 * params < 20e6  # fp32 bytes
    assert count_macs(model, DEPLOY_INPUT_SIZE) < 1.5e9


def test_fuse_matches_eager_and_removes_batchnorm():
    model = _seeded_model()
    model.train()
    with torch.no_grad():  # non-trivial BN statistics, so folding is actually exercised
        for _ in range(3):
            model(torch.rand(2, 3, 128, 160) * 1.5)
    model.eval()
    x = torch.rand(2, 3, 128, 160)
    with torch.no_grad():
        eager = model(x)
        fused = model.fuse()
        assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in fused.modules())
        out = fused.to(memory_format=torch.channels_last)(x.contiguous(memory_format=torch.channels_last))
    for a, b in zip(eager, out):
        torch.testing.assert_close(b, a, atol=1e-4, rtol=1e-4)
