"""A small single-stage (YOLO-style) traffic-sign detector trained on the simulator's renders.

Modules, one job each:
  letterbox    image -> fixed-size network input, and box mapping both ways
  layers       Conv-BN-SiLU and CSP blocks, with BN folding for deployment
  model        backbone + FPN/PAN neck + decoupled head; `build_detector(...)`
  boxes        cell grids, box decoding and (G)IoU shared by loss and postprocess
  assign       centre-sampling target assignment
  loss         `compute_loss(outputs, targets) -> {"obj", "cls", "box", "total"}`
  postprocess  `decode(outputs, conf_threshold)` and class-aware `nms(...)` (OpenCV)
  augment      box-exact photometric and scale-jitter augmentation
  data         the JSONL dataset and its collate function
  ema          exponential moving average of weights
  map50        mAP@0.5 on a dataset (the validation metric of training)
  weights      checkpoint save (atomic) and weights-only load, `WeightsError`
  train        the training loop and its CLI (`python -m avsim.perception.detector.train`)
  infer        `SignDetectorRunner`: image -> list[Detection]

Frames: "image" pixels are the camera image's continuous pixel coordinates (pixel i
covers [i, i+1)); "input" pixels are the same in the letterboxed network input.
"""
