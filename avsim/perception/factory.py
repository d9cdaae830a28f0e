"""Perception registry: builds the configured perception for a scene."""

from __future__ import annotations

from collections.abc import Callable

import mujoco

from avsim.config import PerceptionConfig
from avsim.perception.base import Perception
from avsim.perception.oracle import OraclePerception
from avsim.registry import Registry
from avsim.world.scene import SceneInfo

PerceptionFactory = Callable[[PerceptionConfig, mujoco.MjModel, SceneInfo], Perception]
PERCEPTIONS: Registry[PerceptionFactory] = Registry("perception")
PERCEPTIONS.add("oracle", lambda cfg, model, scene: OraclePerception(model, scene.signs, cfg.min_box_height_px))


def _detector(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo) -> Perception:
    # Imported here so oracle-only runs never import the network code.
    from avsim.perception.detector.perception import DetectorPerception

    return DetectorPerception(config.weights_path, config.min_confidence, config.min_box_height_px)


PERCEPTIONS.add("detector", _detector)


def build_perception(config: PerceptionConfig, model: mujoco.MjModel, scene: SceneInfo) -> Perception:
    return PERCEPTIONS.get(config.kind)(config, model, scene)
