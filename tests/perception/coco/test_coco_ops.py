"""TensorFlow semantics of the ported ops: SAME padding, depthwise channel order, legacy bilinear resize."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from avsim.perception.coco.ops import TfConv2d, resize_bilinear_tf, same_padding, upsample_bilinear_tf, upscale_bilinear_tf


@pytest.mark.parametrize("size,kernel,stride,expected", [
    (512, 3, 2, (0, 1)),  # TF puts the odd pixel after: PyTorch's padding=1 would shift every output
    (512, 5, 2, (1, 2)),
    (511, 3, 2, (1, 1)),
    (128, 3, 1, (1, 1)),
    (128, 5, 1, (2, 2)),
    (32, 1, 1, (0, 0)),
])
def test_same_padding_puts_the_odd_pixel_after(size, kernel, stride, expected):
    assert same_padding(size, kernel, stride) == expected


def _tf_same_conv_reference(x, kernel_hwio, stride, depthwise):
    """SAME conv computed the long way: explicit TF padding, then a VALID conv, in float64."""
    kh, kw, cin, cout = kernel_hwio.shape
    top, bottom = same_padding(x.shape[2], kh, stride)
    left, right = same_padding(x.shape[3], kw, stride)
    padded = F.pad(x.double(), (left, right, top, bottom))
    if depthwise:
        weight = torch.from_numpy(kernel_hwio.transpose(2, 3, 0, 1).reshape(cin * cout, 1, kh, kw)).double()
        return F.conv2d(padded, weight, stride=stride, groups=cin)
    return F.conv2d(padded, torch.from_numpy(kernel_hwio.transpose(3, 2, 0, 1)).double(), stride=stride)


@pytest.mark.parametrize("grad", [False, True], ids=["inference", "autograd"])
@pytest.mark.parametrize("kernel,stride,depthwise,multiplier", [(3, 2, False, 1), (5, 2, True, 1), (3, 1, True, 2), (1, 1, False, 1)])
def test_conv_matches_tf_same_padding_on_both_paths(grad, kernel, stride, depthwise, multiplier):
    rng = np.random.default_rng(0)
    cin, cout = 6, (6 * multiplier if depthwise else 5)
    kernel_hwio = rng.normal(size=(kernel, kernel, cin, multiplier if depthwise else cout)).astype(np.float32)
    x = torch.from_numpy(rng.normal(size=(1, cin, 16, 24)).astype(np.float32))
    conv = TfConv2d(kernel_hwio, (stride, stride), "SAME", depthwise)
    with torch.set_grad_enabled(grad):
        y = conv(x.requires_grad_(grad))
    expected = _tf_same_conv_reference(x.detach(), kernel_hwio, stride, depthwise)
    assert y.shape == expected.shape == (1, cout, 16 // stride, 24 // stride)
    assert torch.allclose(y.detach().double(), expected, atol=1e-4)


def test_hard_swish_uses_the_graphs_constant_on_both_paths():
    kernel = np.ones((1, 1, 1, 1), np.float32)
    conv = TfConv2d(kernel, (1, 1), "SAME", False, activation="HardSwish", hard_swish_scale=0.16662598)
    x = torch.linspace(-5, 5, 41).reshape(1, 1, 1, 41)
    expected = (0.16662598 * x) * torch.clamp(x + 3, 0, 6)
    with torch.inference_mode():
        fast = conv(x)
    slow = conv(x.clone().requires_grad_(True))
    assert torch.allclose(fast, expected, atol=1e-6) and torch.allclose(slow.detach(), expected, atol=1e-6)


def _tfjs_resize_reference(image, out_h, out_w):
    """TF.js's CPU ResizeBilinear kernel (align_corners = half_pixel_centers = False), loop by loop."""
    in_h, in_w, channels = image.shape
    out = np.zeros((out_h, out_w, channels), np.float64)
    for r in range(out_h):
        src_r = in_h / out_h * r
        r0, r1 = max(0, int(np.floor(src_r))), min(in_h - 1, int(np.ceil(src_r)))
        fr = src_r - r0
        for c in range(out_w):
            src_c = in_w / out_w * c
            c0, c1 = max(0, int(np.floor(src_c))), min(in_w - 1, int(np.ceil(src_c)))
            fc = src_c - c0
            top = image[r0, c0] + (image[r0, c1] - image[r0, c0]) * fc
            bottom = image[r1, c0] + (image[r1, c1] - image[r1, c0]) * fc
            out[r, c] = top + (bottom - top) * fr
    return out


@pytest.mark.parametrize("in_hw,out_hw", [((30, 40), (32, 32)), ((12, 10), (24, 20)), ((48, 64), (16, 21))])
def test_resize_is_tfs_legacy_bilinear_not_half_pixel(in_hw, out_hw):
    image = np.random.default_rng(1).uniform(0, 255, (*in_hw, 3))
    x = torch.from_numpy(image.astype(np.float32)).permute(2, 0, 1).unsqueeze(0)
    ours = resize_bilinear_tf(x, out_hw)[0].permute(1, 2, 0).numpy()
    expected = _tfjs_resize_reference(image.astype(np.float32).astype(np.float64), *out_hw)
    assert np.abs(ours - expected).max() < 1e-3
    half_pixel = F.interpolate(x, size=out_hw, mode="bilinear", align_corners=False)[0].permute(1, 2, 0).numpy()
    assert np.abs(half_pixel - expected).max() > 1.0  # what PyTorch's default would have got wrong


def test_integer_upsampling_equals_the_general_resize():
    x = torch.rand(1, 5, 8, 12).contiguous(memory_format=torch.channels_last)
    fast = upsample_bilinear_tf(x, (2, 2))
    assert fast.is_contiguous(memory_format=torch.channels_last)
    assert torch.allclose(fast, resize_bilinear_tf(x, (16, 24)), atol=1e-6)


@pytest.mark.parametrize("factor", [2, 4])
def test_power_of_two_upscaling_is_the_general_resize_bit_for_bit(factor):
    x = torch.from_numpy(np.random.default_rng(2).uniform(-20, 300, (1, 3, 9, 14)).astype(np.float32))
    fast = upscale_bilinear_tf(x, factor)
    assert fast.is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(fast, resize_bilinear_tf(x, (9 * factor, 14 * factor)))


def test_power_of_two_upscaling_of_pixels_equals_the_native_kernel():
    """On 8-bit pixels every lerp by 1/2 is exact, so the deployed input is what it was with `upsample_bilinear_tf`."""
    pixels = torch.from_numpy(np.random.default_rng(3).integers(0, 256, (1, 3, 40, 56)).astype(np.float32))
    assert torch.equal(upscale_bilinear_tf(pixels, 2), upsample_bilinear_tf(pixels, (2, 2)))
    with pytest.raises(ValueError, match="power-of-two"):
        upscale_bilinear_tf(pixels, 3)
