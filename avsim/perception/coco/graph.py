"""Read a TF.js graph model: the node list of `model.json` and its weights, dequantised.

A TF.js graph model is a JSON file with
- `modelTopology.node`: the TensorFlow GraphDef's nodes, each {name, op, input, attr}; an
  input is another node's name, with `:k` for its k-th output and `^` for a control edge;
- `weightsManifest`: groups of weight specs {name, shape, dtype, quantization?} whose
  bytes lie back to back, in spec order, in the group's binary files.
`Const` nodes hold no value in the JSON: their value is the weight of the same name.

Quantised weights: `{"quantization": {"dtype": "float16"}}` stores each value as an IEEE
half float (2 bytes, little-endian) of a float32 tensor; `uint8`/`uint16` store
`value = q * scale + min`. Dequantisation gives the float32 tensor TF.js itself uses.
Attribute values come in the GraphDef's JSON form: strings base64-encoded, ints as decimal
strings, lists as {"list": {"i": [...]}} etc.; `node_attrs` decodes them into plain Python.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from avsim.perception.coco.fetch import CocoWeightsError

_DTYPES = {"float32": np.float32, "int32": np.int32, "bool": np.bool_}


@dataclass(frozen=True)
class GraphNode:
    """One node: `inputs` are (producer name, output index) pairs, control edges dropped."""

    name: str
    op: str
    inputs: tuple[tuple[str, int], ...]
    attrs: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TfjsGraph:
    """The nodes in file order and the constant tensors by name (float32 dequantised, int32)."""

    nodes: tuple[GraphNode, ...]
    constants: dict[str, np.ndarray]
    input_shapes: dict[str, tuple[int, ...]]

    def node(self, name: str) -> GraphNode:
        """The graph node called `name` (KeyError if there is none)."""
        for node in self.nodes:
            if node.name == name:
                return node
        raise KeyError(name)


def _attr_value(value: dict[str, Any]) -> Any:
    """One GraphDef AttrValue in JSON form -> str, int, float, bool, list or dtype name."""
    if "s" in value:
        return base64.b64decode(value["s"]).decode()
    if "i" in value:
        return int(value["i"])
    if "f" in value:
        return float(value["f"])
    if "b" in value:
        return bool(value["b"])
    if "type" in value:
        return value["type"]
    if "list" in value:
        items = value["list"]
        if "s" in items:
            return [base64.b64decode(s).decode() for s in items["s"]]
        if "i" in items:
            return [int(i) for i in items["i"]]
        if "f" in items:
            return [float(f) for f in items["f"]]
        return []
    if "shape" in value:
        return [int(d.get("size", -1)) for d in value["shape"].get("dim", [])]
    return value


def node_attrs(raw: dict[str, Any]) -> dict[str, Any]:
    """A node's raw TF.js attributes as plain Python values (ints, floats, strings, lists)."""
    return {key: _attr_value(value) for key, value in raw.items()}


def _parse_input(text: str) -> tuple[str, int] | None:
    if text.startswith("^"):
        return None  # control dependency: no data flows
    name, _, index = text.partition(":")
    return name, int(index) if index else 0


def _read_weights(manifest: list[dict[str, Any]], folder: Path) -> dict[str, np.ndarray]:
    """Every weight of every manifest group, dequantised to its original dtype."""
    weights = {}
    for group in manifest:
        blob = b"".join((folder / path).read_bytes() for path in group["paths"])
        offset = 0
        for spec in group["weights"]:
            shape = tuple(int(d) for d in spec["shape"])
            count = int(np.prod(shape)) if shape else 1
            quant = spec.get("quantization")
            if quant is None:
                dtype = np.dtype(_DTYPES[spec["dtype"]]).newbyteorder("<")
                values = np.frombuffer(blob, dtype, count, offset)
                offset += count * dtype.itemsize
            elif quant["dtype"] == "float16":
                values = np.frombuffer(blob, np.dtype("<f2"), count, offset).astype(np.float32)
                offset += count * 2
            elif quant["dtype"] in ("uint8", "uint16"):
                dtype = np.dtype("<u1" if quant["dtype"] == "uint8" else "<u2")
                values = np.frombuffer(blob, dtype, count, offset) * np.float32(quant["scale"]) + np.float32(quant["min"])
                offset += count * dtype.itemsize
            else:
                raise ValueError(f"weight {spec['name']}: unknown quantisation {quant['dtype']!r}")
            weights[spec["name"]] = np.asarray(values, dtype=_DTYPES[spec["dtype"]]).reshape(shape).copy()
        if offset != len(blob):
            raise ValueError(f"weights manifest describes {offset} bytes, the files hold {len(blob)}")
    return weights


def read_graph(json_path: Path, bin_folder: Path | None = None) -> TfjsGraph:
    """Parse a TF.js graph model; the binary files are looked up beside the JSON by default.

    Raises CocoWeightsError when the files do not form a graph model.
    """
    try:
        model = json.loads(Path(json_path).read_text())
        topology = model["modelTopology"]["node"]
        weights = _read_weights(model["weightsManifest"], Path(bin_folder or Path(json_path).parent))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CocoWeightsError(f"{json_path} is not a readable TF.js graph model ({type(exc).__name__}: {exc}); "
                               "fetch it again with `python -m avsim.perception.coco.fetch`") from exc
    nodes, constants, input_shapes = [], {}, {}
    for raw in topology:
        attrs = node_attrs(raw.get("attr", {}))
        if raw["op"] == "Const":
            constants[raw["name"]] = weights[raw["name"]]
            continue
        if raw["op"] == "Placeholder":
            input_shapes[raw["name"]] = tuple(attrs.get("shape", []))
        inputs = tuple(p for p in (_parse_input(text) for text in raw.get("input", [])) if p is not None)
        nodes.append(GraphNode(raw["name"], raw["op"], inputs, attrs))
    return TfjsGraph(tuple(nodes), constants, input_shapes)
