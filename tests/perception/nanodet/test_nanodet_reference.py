"""The NanoDet interpreter against the TF.js runtime itself, on avsim renders (slow: runs Node).

`tests/perception/coco/node_reference/graph_outputs.js` runs nanodet.json/.bin with the TF.js runtime
pinned there for the COCO port's reference (tfjs-core, -converter, -backend-cpu 4.22.0, pure-JS CPU) and
writes the six raw outputs. Each render goes in at the graph's own 416 x 416 (a bilinear resize of the
frame, normalised as NanoDet takes it), the same tensor on both sides; every class score and box-side logit
must agree within the tolerances below.
"""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from avsim.perception.coco.preprocess import image_tensor
from avsim.perception.nanodet import fetch
from avsim.perception.nanodet.network import GRAPH_INPUT_HW, SCORE_OUTPUTS, SIDE_OUTPUTS, NanoDetNetwork, normalise_bgr
from tests.perception.coco.test_coco_reference import node_reference  # noqa: F401 (the pinned TF.js runtime)
from tests.perception.reference_renders import render_views

SCORE_TOL = 1e-5  # class scores, after the sigmoid (measured here: 1.3e-6)
LOGIT_TOL = 5e-4  # box-side logits, before the softmax (values of order 10; measured here: 2.5e-5)
# One render of each town, front and side, near and far: each is one Node process (about 5 s).
VIEWS = ("town03/standard/front/25m", "town07/near/side/18m", "town10/far/front/40m")


@pytest.mark.slow
def test_the_interpreter_matches_the_tfjs_runtime_on_renders(node_reference, tmp_path):  # noqa: F811
    torch.set_num_threads(1)
    json_path, bin_path = fetch.model_paths()
    network = NanoDetNetwork(json_path)
    frames = [(view, frame) for view, frame in render_views() if view in VIEWS]
    assert len(frames) == len(VIEWS)
    names = [*SCORE_OUTPUTS, *SIDE_OUTPUTS]
    worst = {"score": 0.0, "logit": 0.0}
    for index, (view, frame) in enumerate(frames):
        x = normalise_bgr(F.interpolate(image_tensor(frame), size=GRAPH_INPUT_HW, mode="bilinear", align_corners=False))
        path = tmp_path / f"{index}.f32"
        x.numpy().astype("<f4").tofile(path)
        job = tmp_path / f"{index}.json"
        prefix = tmp_path / f"{index}.out"
        job.write_text(json.dumps({"model_json": str(json_path), "model_bin": str(bin_path), "outputs": names,
                                   "input": {"path": str(path), "shape": list(x.shape)}, "out_prefix": str(prefix)}))
        subprocess.run(["node", "graph_outputs.js", str(job)], cwd=node_reference, check=True, timeout=600,
                       env={**os.environ, "NODE_OPTIONS": ""}, capture_output=True)
        meta = json.loads((tmp_path / f"{index}.out.json").read_text())
        assert meta["versions"]["backend"] == "cpu"
        with torch.inference_mode():
            ours = [t for pair in network(x) for t in pair]
        ours = dict(zip([n for pair in zip(SCORE_OUTPUTS, SIDE_OUTPUTS) for n in pair], ours))
        for name in names:
            reference = np.fromfile(f"{prefix}.{name}.f32", dtype="<f4").reshape(meta["shapes"][name])
            difference = float(np.abs(ours[name].numpy() - reference).max())
            kind = "score" if name in SCORE_OUTPUTS else "logit"
            worst[kind] = max(worst[kind], difference)
            assert difference <= (SCORE_TOL if kind == "score" else LOGIT_TOL), f"{view} {name}: {difference:.2e}"
    print(f"\nTF.js reference: {len(frames)} renders; max score difference {worst['score']:.2e}, "
          f"max box-side logit difference {worst['logit']:.2e}")
