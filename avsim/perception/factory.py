"""Perception registry: builds the configured perception for a scene."""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from avsim.config import PerceptionConfig
from avsim.perception.base import Perception
from avsim.perception.oracle import OraclePerception
from avsim.registry import Registry
from avsim.world.scene import SceneInfo

# (config, model, scene, seed) -> Perception; the seed is the run's scenario.seed (sensor noise).
PerceptionFactory = Callable[[PerceptionConfig, mujoco.MjModel, SceneInfo, int], Perception]
PERCEPTIONS: Registry[PerceptionFactory] = Registry("perception")
PERCEPTIONS.add("oracle", lambda cfg, model, scene, seed: OraclePerception(model, scene.signs, cfg.min_box_height_px))


def _detector(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int) -> Perception:
    # Imported here so oracle-only runs never import the network code.
    from avsim.perception.detector.perception import DetectorPerception
    from avsim.sensors.noise import SensorNoise

    return DetectorPerception(config.weights_path, config.min_confidence, config.min_box_height_px, config.threads,
                              SensorNoise(config.sensor_noise_std, seed),
                              {"front": config.front_roi_px, "side": config.side_roi_px})


PERCEPTIONS.add("detector", _detector)


def _regions(config: PerceptionConfig) -> dict[str, tuple[int, int, int, int]]:
    return {"front": config.front_roi_px, "side": config.side_roi_px}


def _coco(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int) -> Perception:
    # Imported here so runs without it never import the port (nor need its fetched weights).
    from avsim.perception.coco.model import load_centernet
    from avsim.perception.coco.runner import CocoRunner
    from avsim.perception.frame import FramePerception
    from avsim.sensors.noise import SensorNoise

    runner = CocoRunner(load_centernet(), config.coco_input, config.coco_upscale, config.min_confidence)
    return FramePerception("coco", runner, config.min_box_height_px, config.threads,
                           SensorNoise(config.sensor_noise_std, seed), _regions(config))


def _onnx(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int) -> Perception:
    from avsim.perception.frame import FramePerception
    from avsim.perception.onnx.runner import OnnxRunner
    from avsim.sensors.noise import SensorNoise

    runner = OnnxRunner(config.onnx_path, config.onnx_classes, config.min_confidence, config.threads)
    return FramePerception("onnx", runner, config.min_box_height_px, config.threads,
                           SensorNoise(config.sensor_noise_std, seed), _regions(config))


PERCEPTIONS.add("coco", _coco)
PERCEPTIONS.add("onnx", _onnx)


def build_perception(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int = 0) -> Perception:
    """The configured perception; `seed` (the run's scenario.seed) seeds its sensor noise."""
    return PERCEPTIONS.get(config.kind)(config, model, scene, seed)
