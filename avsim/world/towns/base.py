"""What a town is, and the registries of towns and stop-sign placements."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.registry import Registry
from avsim.world.road import RoadLayout
from avsim.world.signs import PlacedSign

# Scenery builders get the spec and a seeded generator and return the extra
# (non-target) signs they placed; their textures are added by the scene.
SceneryBuilder = Callable[[mujoco.MjSpec, RoadLayout, np.random.Generator], list[PlacedSign]]

# Standard bottom height of a sign face in towns (MUTCD: 7 ft) [m].
SIGN_BOTTOM_M = 2.1
# Objects taller than the camera within this lateral band right of the travelled lane,
# near the stop line, would hide the stop sign; builders keep it clear.
SIGHT_CORRIDOR_M = 8.0
SIGHT_CORRIDOR_START_X_M = -70.0


@dataclass(frozen=True)
class Town:
    """A registered town: its road cross-section, ground and scenery."""

    name: str
    description: str
    layout: RoadLayout
    ground_material: str
    build_scenery: SceneryBuilder


TOWNS: Registry[Town] = Registry("town")

# Lateral offset of the stop sign's post beyond the right edge of the travelled lane [m].
PLACEMENTS: Registry[float] = Registry("placement")
PLACEMENTS.add("standard", 2.0)
PLACEMENTS.add("near", 0.5)
PLACEMENTS.add("far", 5.5)
