"""Perception registry: builds the configured perception for a scene."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
from typing import TYPE_CHECKING

import mujoco

from avsim.config import CameraConfig, PerceptionConfig
from avsim.errors import ConfigError
from avsim.perception.base import NoPerception, Perception
from avsim.perception.oracle import OraclePerception
from avsim.registry import Registry
from avsim.world.scene import SceneInfo

if TYPE_CHECKING:
    from avsim.perception.frame import FrameDetector

# (config, model, scene, seed, detectors) -> Perception; the seed is the run's scenario.seed (sensor
# noise); detectors: where a pixel perception takes its network from (None: build its own).
PerceptionFactory = Callable[[PerceptionConfig, mujoco.MjModel, SceneInfo, int, "FrameDetectorCache | None"], Perception]
PERCEPTIONS: Registry[PerceptionFactory] = Registry("perception")
PERCEPTIONS.add("oracle", lambda cfg, camera, model, scene, seed, detectors: OraclePerception(model, scene.signs, cfg.oracle_min_box_height_px))
PERCEPTIONS.add("none", lambda cfg, camera, model, scene, seed, detectors: NoPerception())


# Perceptions that run on pixels alone, as frame detectors: config -> an object with
# detect(image_rgb, camera, region_px=...) -> list[Detection]. `avsim detect` runs these on
# image files; the closed loop wraps them in a FramePerception (render, noise, range).
FrameDetectorFactory = Callable[[PerceptionConfig], "FrameDetector"]
FRAME_DETECTORS: Registry[FrameDetectorFactory] = Registry("pixel perception")


def _detector_frames(config: PerceptionConfig) -> "FrameDetector":
    # Imported here so oracle-only runs never import the network code.
    from avsim.perception.detector.infer import SignDetectorRunner
    from avsim.perception.detector.weights import resolve_weights_path

    return SignDetectorRunner(resolve_weights_path(config.weights_path), conf_threshold=config.min_confidence,
                              num_threads=config.threads, precision=config.detector_precision,
                              native_pixels=config.detector_native_pixels)


def _coco_frames(config: PerceptionConfig) -> "FrameDetector":
    # Imported here so runs without it never import the port (nor need its fetched weights).
    import torch

    from avsim.perception.coco.bf16 import Bf16CenterNet
    from avsim.perception.coco.infer import CocoRunner
    from avsim.perception.coco.model import load_centernet
    from avsim.perception.cpu_bf16 import arithmetic

    torch.set_num_threads(config.threads)
    model = load_centernet()
    # The key is read by name, not through network_arithmetic, so that the key-owner test sees what this reads.
    if arithmetic(config.coco_precision, "perception.coco_precision") == "bf16":
        model = Bf16CenterNet(model)
    return CocoRunner(model, config.coco_input, config.coco_upscale, config.min_confidence)


def _yolo_frames(config: PerceptionConfig) -> "FrameDetector":
    # Imported here so runs without it never import the reader (nor need its fetched files).
    import torch

    from avsim.perception.cpu_bf16 import arithmetic
    from avsim.perception.yolo.bf16 import Bf16Yolo
    from avsim.perception.yolo.model import load_yolo
    from avsim.perception.yolo.infer import YoloRunner

    torch.set_num_threads(config.threads)
    model = load_yolo(config.yolo_cfg or None, config.yolo_weights or None, config.yolo_names or None)
    bf16 = arithmetic(config.yolo_precision, "perception.yolo_precision") == "bf16"  # read by name, as for coco
    return YoloRunner(Bf16Yolo(model) if bf16 else model, config.yolo_input,
                      config.yolo_upscale, config.min_confidence)


def _nanodet_frames(config: PerceptionConfig) -> "FrameDetector":
    # Imported here so runs without it never import the interpreter (nor need its fetched files).
    import torch

    from avsim.perception.nanodet.model import INPUT_UPSCALE, NMS_IOU, load_nanodet
    from avsim.perception.yolo.infer import YoloRunner

    torch.set_num_threads(config.threads)
    return YoloRunner(load_nanodet(), "upscale", INPUT_UPSCALE, config.min_confidence, iou_threshold=NMS_IOU)


def _onnx_frames(config: PerceptionConfig) -> "FrameDetector":
    from avsim.perception.onnx.infer import OnnxRunner

    return OnnxRunner(config.onnx_path, config.onnx_classes, config.min_confidence, config.threads)


def _ensemble_frames(config: PerceptionConfig) -> "FrameDetector":
    from avsim.perception.ensemble import EnsembleDetector

    return EnsembleDetector({name: FRAME_DETECTORS.get(name)(config) for name in config.ensemble_members},
                            config.ensemble_fusion, config.ensemble_k)


FRAME_DETECTORS.add("detector", _detector_frames)
FRAME_DETECTORS.add("coco", _coco_frames)
FRAME_DETECTORS.add("yolo", _yolo_frames)
FRAME_DETECTORS.add("nanodet", _nanodet_frames)
FRAME_DETECTORS.add("onnx", _onnx_frames)
FRAME_DETECTORS.add("ensemble", _ensemble_frames)


def build_frame_detector(config: PerceptionConfig) -> "FrameDetector":
    """The configured perception as a detector of image pixels, behind its purifier if it has one
    (`perception.purify`); the oracle has none (it reads a scene)."""
    if config.kind == "oracle":
        raise ConfigError("the oracle perception reads ground truth from a simulated scene, not from pixels, so it cannot "
                          f"run on an image; choose one of: {', '.join(FRAME_DETECTORS.names())}")
    from avsim.perception.purify import PurifiedDetector, build_purifier

    detector = FRAME_DETECTORS.get(config.kind)(config)
    purifier = build_purifier(config)
    return detector if purifier is None else PurifiedDetector(detector, purifier)


def network_files_key(config: PerceptionConfig) -> tuple:
    """What decides whether a perception's networks can be built: its kind and every name, path and
    mode it holds (weights files, precisions, input modes, ensemble members), not its numbers
    (thresholds, upscales, threads), which a built network takes as they come."""
    return (config.kind, *((f.name, getattr(config, f.name)) for f in fields(config)
                           if isinstance(getattr(config, f.name), (str, tuple))))


_NETWORKS_BUILT: set[tuple] = set()


def check_networks_build(config: PerceptionConfig) -> None:
    """Build the perception's networks and drop them, once per `network_files_key` in this process:
    missing, corrupt or unfetched weights are then refused in one line (their own errors) before a
    batch's first run, not in each of its runs. The oracle and `none` have no network."""
    if config.kind in ("oracle", "none"):
        return
    key = network_files_key(config)
    if key not in _NETWORKS_BUILT:
        build_frame_detector(config)
        _NETWORKS_BUILT.add(key)


class FrameDetectorCache:
    """One frame detector per distinct perception config, shared by the runs that use it.

    The lock-step batch (`avsim.lockstep`) builds its runs' perceptions from one cache,
    so that cars with the same perception share one network and its calls. A detector holds no
    per-run state (the per-run sensor noise lives in the perception around it), so sharing it
    changes no result.
    """

    def __init__(self) -> None:
        self._detectors: dict[PerceptionConfig, FrameDetector] = {}

    def get(self, config: PerceptionConfig) -> "FrameDetector":
        """The frame detector of `config`, built on first use."""
        if config not in self._detectors:
            self._detectors[config] = build_frame_detector(config)
        return self._detectors[config]


def networks_per_frame(config: PerceptionConfig) -> int:
    """How many networks the perception runs on each camera frame: 0 for the oracle (it renders
    segmentation instead), the members of an ensemble, else 1."""
    return {"oracle": 0, "ensemble": len(config.ensemble_members)}.get(config.kind, 1)


def _frame_perception(config: PerceptionConfig, camera: CameraConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int,
                      detectors: FrameDetectorCache | None) -> Perception:
    from avsim.perception.frame import FramePerception
    from avsim.sensors.noise import SensorNoise
    from avsim.sensors.regions import resolve_regions_px

    detector = build_frame_detector(config) if detectors is None else detectors.get(config)
    return FramePerception(config.kind, detector, config.min_box_height_px, config.threads,
                           SensorNoise(config.sensor_noise_std, seed),
                           resolve_regions_px({"front": config.front_roi_px, "side": config.side_roi_px}, camera))


# The `perception.*` keys each kind reads besides `kind` (`avsim.config_owners` refuses a key set
# for a perception that does not read it; a test checks these against the keys really read).
# Every pixel perception reads FRAME_KEYS (FramePerception, the purifier) and its network's keys;
# an ensemble reads the keys of each network in `ensemble_members`.
FRAME_KEYS = ("min_box_height_px", "threads", "sensor_noise_std", "front_roi_px", "side_roi_px", "purify")
NETWORK_KEYS = {
    "detector": ("min_confidence", "weights_path", "detector_precision", "detector_native_pixels"),
    "coco": ("min_confidence", "coco_input", "coco_upscale", "coco_precision"),
    "yolo": ("min_confidence", "yolo_cfg", "yolo_weights", "yolo_names", "yolo_input", "yolo_upscale", "yolo_precision"),
    "nanodet": ("min_confidence",),
    "onnx": ("min_confidence", "onnx_path", "onnx_classes"),
    "ensemble": ("ensemble_fusion", "ensemble_members", "ensemble_k"),
}
PERCEPTION_KEYS = {"oracle": ("oracle_min_box_height_px",), "none": (),
                   **{kind: FRAME_KEYS + keys for kind, keys in NETWORK_KEYS.items()}}
# Keys read only under one value of another key: key -> (that key, the value).
CONDITIONAL_KEYS = {
    "coco_upscale": ("coco_input", "upscale"),
    "yolo_upscale": ("yolo_input", "upscale"),
    "purify_jpeg_quality": ("purify", "jpeg"),
    "purify_median_kernel_px": ("purify", "median"),
    "ensemble_k": ("ensemble_fusion", "k_of_n"),
}


def perception_keys(config: PerceptionConfig) -> frozenset[str]:
    """The `perception.*` keys (without the section) that the perception of `config` reads."""
    keys = set(PERCEPTION_KEYS.get(config.kind, ()))
    if config.kind == "ensemble":
        keys.update(key for member in config.ensemble_members for key in NETWORK_KEYS[member])
    for key, (switch, value) in CONDITIONAL_KEYS.items():
        if switch in keys and getattr(config, switch) == value:
            keys.add(key)
        else:
            keys.discard(key)
    return frozenset(keys)


# The networks whose arithmetic is a setting, by the key that sets it.
PRECISION_KEYS = {"detector": "detector_precision", "coco": "coco_precision", "yolo": "yolo_precision"}


def network_arithmetic(config: PerceptionConfig, network: str) -> str:
    """What `network` (a key of PRECISION_KEYS) runs as on this CPU under `config`, "fp32" or "bf16"; "bf16" on
    a CPU without bf16 kernels is a one-line ConfigError naming the key."""
    from avsim.perception.cpu_bf16 import arithmetic  # imports torch: only where a network is asked about

    key = PRECISION_KEYS[network]
    return arithmetic(getattr(config, key), f"perception.{key}")


def network_arithmetics(config: PerceptionConfig) -> dict[str, str]:
    """`network_arithmetic` of each network of `config` that has an arithmetic setting, by network
    ({"detector": "bf16"}; {} for the oracle), so that a batch can refuse bf16 before its first run."""
    read = perception_keys(config)
    return {network: network_arithmetic(config, network) for network, key in PRECISION_KEYS.items() if key in read}


PERCEPTIONS.add("detector", _frame_perception)
PERCEPTIONS.add("coco", _frame_perception)
PERCEPTIONS.add("yolo", _frame_perception)
PERCEPTIONS.add("nanodet", _frame_perception)
PERCEPTIONS.add("onnx", _frame_perception)
PERCEPTIONS.add("ensemble", _frame_perception)


def build_perception(config: PerceptionConfig, camera: CameraConfig, model: mujoco.MjModel, scene: SceneInfo,
                     seed: int = 0, detectors: FrameDetectorCache | None = None) -> Perception:
    """The configured perception of the cameras `camera` (a pixel perception's regions of interest
    follow it); `seed` (the run's scenario.seed) seeds its sensor noise; a pixel perception takes its
    network from `detectors` when given (shared), else builds its own."""
    return PERCEPTIONS.get(config.kind)(config, camera, model, scene, seed, detectors)
