"""The reference for avsim's Darknet reader: OpenCV 4's own Darknet importer (cv2.dnn.readNetFromDarknet).

Runs in its own virtual environment (requirements.txt: opencv-python-headless 4.14, the last
series with the importer; OpenCV 5 dropped it), never inside avsim's:

  python reference.py JOB.json

JOB.json: {"cfg": ".../yolov3-tiny.cfg", "weights": ".../yolov3-tiny.weights",
           "inputs": ["blob0.npy", ...],      # (1, 3, H, W) float32 RGB in 0..1
           "out": "outputs.json"}
For each input it writes INPUT.out.npy: the [yolo] outputs concatenated, (N, 5 + C) float32 rows
cx, cy, w, h (fractions of the input), objectness, per-class scores (objectness x class
probability, zeroed by OpenCV below its own threshold). outputs.json records the versions.
"""

import json
import sys

import cv2
import numpy as np


def main(job_path: str) -> None:
    with open(job_path) as handle:
        job = json.load(handle)
    net = cv2.dnn.readNetFromDarknet(job["cfg"], job["weights"])
    net.setPreferableBackend(cv2.dnn.DNN_BACKEND_OPENCV)
    net.setPreferableTarget(cv2.dnn.DNN_TARGET_CPU)
    names = net.getUnconnectedOutLayersNames()
    outputs = []
    for path in job["inputs"]:
        net.setInput(np.load(path))
        rows = np.concatenate([np.asarray(o, np.float32).reshape(-1, o.shape[-1]) for o in net.forward(names)])
        np.save(path + ".out.npy", rows)
        outputs.append(path + ".out.npy")
    with open(job["out"], "w") as handle:
        json.dump({"versions": {"opencv": cv2.__version__, "numpy": np.__version__}, "output_layers": list(names),
                   "outputs": outputs}, handle)


if __name__ == "__main__":
    main(sys.argv[1])
