"""Reading a TF.js graph model: attributes, control edges, float16 dequantisation, bad files."""

import base64
import json

import numpy as np
import pytest

from avsim.perception.coco.fetch import CocoWeightsError
from avsim.perception.coco.graph import read_graph


def _b64(text: str) -> str:
    return base64.b64encode(text.encode()).decode()


def _write_graph(folder, weights_bytes: bytes, manifest: list[dict]) -> None:
    nodes = [
        {"name": "x", "op": "Placeholder", "attr": {"shape": {"shape": {"dim": [{"size": "1"}, {"size": "4"}]}}}},
        {"name": "w", "op": "Const"},
        {"name": "k", "op": "Const"},
        {"name": "y", "op": "Mul", "input": ["x", "w", "^k"], "attr": {"padding": {"s": _b64("SAME")},
                                                                       "strides": {"list": {"i": ["1", "2", "2", "1"]}},
                                                                       "keep_dims": {"b": True}, "epsilon": {"f": 0.001}}},
    ]
    (folder / "model.json").write_text(json.dumps({
        "format": "graph-model", "modelTopology": {"node": nodes},
        "weightsManifest": [{"paths": ["model.bin"], "weights": manifest}]}))
    (folder / "model.bin").write_bytes(weights_bytes)


def test_float16_weights_dequantise_exactly_and_attributes_decode(tmp_path):
    values = np.array([0.1, -2.5, 3.0e-3, 65504.0], np.float32)
    half = values.astype("<f2")
    ints = np.array([7, -1], "<i4")
    manifest = [{"name": "w", "shape": [4], "dtype": "float32", "quantization": {"dtype": "float16", "original_dtype": "float32"}},
                {"name": "k", "shape": [2], "dtype": "int32"}]
    _write_graph(tmp_path, half.tobytes() + ints.tobytes(), manifest)
    graph = read_graph(tmp_path / "model.json")
    assert graph.constants["w"].dtype == np.float32
    assert np.array_equal(graph.constants["w"], half.astype(np.float32))
    assert np.array_equal(graph.constants["k"], ints)
    node = graph.node("y")
    assert node.inputs == (("x", 0), ("w", 0))  # the control edge ^k carries no data
    assert node.attrs == {"padding": "SAME", "strides": [1, 2, 2, 1], "keep_dims": True, "epsilon": pytest.approx(0.001)}
    assert graph.input_shapes == {"x": (1, 4)}


def test_weights_file_of_the_wrong_length_is_refused(tmp_path):
    manifest = [{"name": "w", "shape": [4], "dtype": "float32"}, {"name": "k", "shape": [2], "dtype": "int32"}]
    _write_graph(tmp_path, b"\x00" * 10, manifest)
    with pytest.raises(CocoWeightsError, match="not a readable TF.js graph model"):
        read_graph(tmp_path / "model.json")
