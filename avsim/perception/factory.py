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
PERCEPTIONS.add("oracle", lambda cfg, model, scene, seed: OraclePerception(model, scene.signs, cfg.oracle_min_box_height_px))


def _detector(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int) -> Perception:
    # Imported here so oracle-only runs never import the network code.
    from avsim.perception.detector.perception import DetectorPerception
    from avsim.sensors.noise import SensorNoise

    return DetectorPerception(config.weights_path, config.min_confidence, config.min_box_height_px, config.threads,
                              SensorNoise(config.sensor_noise_std, seed),
                              {"front": config.front_roi_px, "side": config.side_roi_px})


PERCEPTIONS.add("detector", _detector)


def build_perception(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo, seed: int = 0) -> Perception:
    """The configured perception; `seed` (the run's scenario.seed) seeds its sensor noise."""
    return PERCEPTIONS.get(config.kind)(config, model, scene, seed)
