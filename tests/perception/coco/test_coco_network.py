"""The ported network and decoding: both conv paths agree, gradients reach the pixels, the tail is the graph's."""

import numpy as np
import pytest
import torch

from avsim.perception.coco import fetch
from avsim.perception.coco.decode import DecodeSpec, decode_detections, decode_logit_detections, topk_lowest_index_first
from avsim.perception.coco.graph import read_graph
from avsim.perception.coco.model import load_centernet
from avsim.perception.coco.network import dense_node_names

# What the fetched graph holds; the port implements each (the tail through `decode`).
GRAPH_OPS = {"Placeholder", "_FusedConv2D", "FusedDepthwiseConv2dNative", "DepthwiseConv2dNative", "Conv2D", "Mul", "Add",
             "Sub", "Relu", "Relu6", "Sigmoid", "Mean", "ResizeBilinear", "ConcatV2", "MaxPool", "TopKV2", "GatherV2",
             "Reshape", "StridedSlice", "ExpandDims", "Cast", "FloorDiv", "FloorMod", "Equal", "Identity"}


@pytest.fixture(scope="module")
def model():
    torch.manual_seed(0)
    return load_centernet()


def _image(height=256, width=320, seed=0):
    rng = np.random.default_rng(seed)
    # Smooth blobs rather than white noise: closer to what the network was trained on.
    small = rng.uniform(0, 255, (1, 3, height // 16, width // 16)).astype(np.float32)
    return torch.nn.functional.interpolate(torch.from_numpy(small), size=(height, width), mode="bilinear")


def test_the_graph_holds_the_expected_ops_and_its_decoding_constants():
    graph = read_graph(fetch.model_paths()[0])
    assert {node.op for node in graph.nodes} == GRAPH_OPS
    assert DecodeSpec.from_graph(graph, dense_node_names(graph)) == DecodeSpec(k=100, stride_px=4.0, num_classes=80)


def test_inference_and_autograd_paths_give_the_same_maps(model):
    image = _image().contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        heat_fast, wh_fast = model.maps(image)
    heat_slow, wh_slow = model.maps(image.clone().requires_grad_(True))
    assert heat_fast.shape == (1, 80, 64, 80) and wh_fast.shape == (1, 4, 64, 80)
    assert torch.allclose(heat_fast, heat_slow.detach(), atol=1e-5)
    assert torch.allclose(wh_fast, wh_slow.detach(), atol=1e-2)  # input pixels; boxes are tens of px


def test_the_stop_sign_heatmap_is_differentiable_in_the_pixels(model):
    image = _image().requires_grad_(True)
    heatmap, _ = model.maps(image)
    heatmap[0, 11].max().backward()
    grad = image.grad
    assert grad is not None and torch.isfinite(grad).all() and grad.abs().sum() > 0


def test_input_sizes_must_be_multiples_of_32(model):
    with pytest.raises(ValueError, match="multiple of 32"):
        with torch.inference_mode():
            model.maps(torch.zeros(1, 3, 100, 128))


def _graph_tail_reference(heatmap, wh, k=100, stride=4.0):
    """The graph's decoding tail in NumPy, NHWC, op by op (ties by the lower flat index, as TF.js)."""
    _, classes, height, width = heatmap.shape
    keypoints = heatmap[0].transpose(1, 2, 0)  # (H, W, C)
    padded = np.pad(keypoints, ((1, 1), (1, 1), (0, 0)), constant_values=-np.inf)
    pooled = np.max([padded[dy:dy + height, dx:dx + width] for dy in range(3) for dx in range(3)], axis=0)
    flat = (keypoints * (keypoints == pooled)).reshape(-1)
    order = sorted(range(flat.size), key=lambda i: (-flat[i], i))[:k]
    rows = []
    wh_flat = wh[0].transpose(1, 2, 0).reshape(-1, 4)
    for index in order:
        cls, cell = index % classes, index // classes
        row, col = cell // width, cell % width
        left, top, right, bottom = wh_flat[row * width + col]
        rows.append([col * stride - left, row * stride - top, col * stride + right, row * stride + bottom, flat[index], cls])
    return np.array(rows, np.float32)


def test_decoding_matches_the_graph_tail_including_ties():
    rng = np.random.default_rng(3)
    # Scores on a coarse grid, so many are tied: the order among ties must be the flat index.
    heatmap = (rng.integers(0, 20, (1, 80, 12, 16)) / 20.0).astype(np.float32)
    wh = rng.uniform(0, 30, (1, 4, 12, 16)).astype(np.float32)
    ours = decode_detections(torch.from_numpy(heatmap), torch.from_numpy(wh)).numpy()[0]
    assert np.array_equal(ours, _graph_tail_reference(heatmap, wh))


def test_topk_breaks_ties_by_the_lower_index():
    values, indices = topk_lowest_index_first(torch.tensor([[0.5, 0.75, 0.5, 0.75, 0.25, 0.5]]), 4)
    assert indices.tolist() == [[1, 3, 0, 2]] and values.tolist() == [[0.75, 0.75, 0.5, 0.5]]


@pytest.mark.parametrize("min_score", [0.0, 0.3, 0.9])
def test_thresholded_decoding_is_the_graphs_rows_filtered(min_score):
    rng = np.random.default_rng(4)
    heatmap = torch.from_numpy((rng.integers(0, 20, (1, 80, 12, 16)) / 20.0).astype(np.float32))
    wh = torch.from_numpy(rng.uniform(0, 30, (1, 4, 12, 16)).astype(np.float32))
    full = decode_detections(heatmap, wh)[0]
    fast = decode_detections(heatmap.contiguous(memory_format=torch.channels_last), wh, min_score=min_score)[0]
    assert torch.equal(fast, full[full[:, 4] >= min_score])


@pytest.mark.parametrize("min_score", [0.1, 0.5])
def test_logit_decoding_is_the_sigmoid_heatmaps_decoding(min_score):
    """Peaks of the logits are the heatmap's peaks (the sigmoid is increasing), so the rows are the same.
    Logits on a 1/8 grid within +-4: distinct logits keep distinct float32 sigmoids, ties stay ties."""
    rng = np.random.default_rng(5)
    logits = torch.from_numpy((rng.integers(-32, 33, (1, 80, 12, 16)) / 8.0).astype(np.float32))
    wh = torch.from_numpy(rng.uniform(0, 30, (1, 4, 12, 16)).astype(np.float32))
    expected = decode_detections(torch.sigmoid(logits), wh, min_score=min_score)
    assert len(expected[0]) > 10
    assert torch.equal(decode_logit_detections(logits, wh, DecodeSpec(), min_score), expected)
    assert torch.equal(decode_logit_detections(logits.bfloat16(), wh.bfloat16(), DecodeSpec(), min_score)[0, :, 4:],
                       expected[0, :, 4:])  # every value of the grid is a bf16 value: the same peaks and scores
