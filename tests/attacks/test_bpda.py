"""BPDA: the deployed purifier forward, the identity backward, so an attack's gradient reaches the texture."""

import pytest
import torch

from avsim.attacks.bpda import bpda, purifier_layer
from avsim.config import PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.purify import build_purifier, purify_tensor


@pytest.mark.parametrize("purify", ["jpeg", "median"])
def test_the_gradient_passes_through_the_purifier_unchanged(purify):
    layer = purifier_layer(PerceptionConfig(purify=purify))
    x = torch.rand(2, 3, 40, 56, generator=torch.Generator().manual_seed(0), requires_grad=True)
    weights = torch.randn(2, 3, 40, 56, generator=torch.Generator().manual_seed(1))
    (layer(x) * weights).sum().backward()
    assert torch.equal(x.grad, weights)


@pytest.mark.parametrize("purify", ["jpeg", "median"])
def test_the_forward_pass_is_the_deployed_purifier(purify):
    config = PerceptionConfig(purify=purify)
    x = torch.rand(1, 3, 40, 56, generator=torch.Generator().manual_seed(2))
    out = purifier_layer(config)(x)
    assert torch.equal(out, purify_tensor(x, build_purifier(config)))
    assert not torch.equal(out, x)


def test_a_gradient_flows_back_through_layers_before_it():
    texture = torch.full((1, 3, 8, 8), 0.5, requires_grad=True)
    out = bpda(lambda t: t.round())(texture * 2)  # round() alone has zero gradient almost everywhere
    out.sum().backward()
    assert torch.equal(texture.grad, torch.full_like(texture, 2.0))


def test_a_step_that_changes_the_shape_is_refused_and_no_purifier_is_an_error():
    with pytest.raises(ValueError, match="keep the input's shape"):
        bpda(lambda t: t[..., :4])(torch.zeros(1, 3, 8, 8, requires_grad=True))
    with pytest.raises(ConfigError, match="no purification"):
        purifier_layer(PerceptionConfig())
