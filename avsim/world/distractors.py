"""Red sign-like roadside boards that are no traffic sign: the availability scenario's distractors.

`scenario.distractors = "red_signs"` puts round and hexagonal red adverts with a white border and
a white word (`avsim.world.textures.make_disc_advert`, `make_hexagon_advert`) along the approach,
on posts at a sign's height, facing the car: red and white, about a stop sign's size and shape,
and nothing a driver must obey. A detector that takes them for stop signs makes the car brake
for nothing. They are props, not signs: no perception's ground truth lists them (the oracle
reports nothing for them), and they are not in `SceneInfo.signs`.

They stand outside the stop sign's sight corridor (`avsim.world.towns.base`), so they never hide
the junction's sign. World frame as in `avsim.world.road` [m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.world.road import RoadLayout
from avsim.world.signs import SignShape, add_plate
from avsim.world.textures import hexagon_outline, make_disc_advert, make_hexagon_advert
from avsim.world.towns.base import SIGHT_CORRIDOR_START_X_M, SIGN_BOTTOM_M

DISC_DIAMETER_M = 0.8
HEXAGON_WIDTH_M = 0.9
# How far beyond the road's edge lines the boards' posts stand [m]: shop boards at the verge.
VERGE_OFFSET_M = 2.5


def _disc(diameter_m: float) -> SignShape:
    angles = np.deg2rad(np.arange(0, 360, 15))  # 24 sides: round at any range a camera resolves it
    r = diameter_m / 2
    return SignShape("red_disc", tuple((r * math.cos(a), r * math.sin(a)) for a in angles), diameter_m, diameter_m)


def _hexagon(width_m: float) -> SignShape:
    # The texture's outline is (x right, y down) as seen from the front; the face plane is
    # (y = viewer's left, z = up), so both axes flip.
    points = tuple((-float(x), -float(y)) for x, y in hexagon_outline(width_m))
    return SignShape("red_hexagon", points, width_m, width_m * math.sqrt(3) / 2)


@dataclass(frozen=True)
class Board:
    """One advert: its shape, word, distance along the road [m] and side (+1 left, -1 right)."""

    kind: str
    word: str
    x_m: float
    side: int


# Right of the road where a stop sign would stand, every 45-50 m (so one at a time is inside a
# policy's 40 m braking gate), and one on the left.
BOARDS = (
    Board("red_disc", "CAFE", -170.0, -1),
    Board("red_hexagon", "PIZZA", -120.0, -1),
    Board("red_hexagon", "MOTEL", -95.0, +1),
    Board("red_disc", "SHOP", SIGHT_CORRIDOR_START_X_M, -1),
)


def add_red_signs(spec: mujoco.MjSpec, layout: RoadLayout) -> None:
    """Add the BOARDS to `spec`, facing traffic on the approach."""
    edge_right_m = layout.lane_edge_y_m
    edge_left_m = -layout.lane_edge_y_m
    for k, board in enumerate(BOARDS):
        if board.kind == "red_disc":
            shape, texture = _disc(DISC_DIAMETER_M), make_disc_advert(board.word)
        else:
            shape, texture = _hexagon(HEXAGON_WIDTH_M), make_hexagon_advert(board.word)
        y_m = edge_right_m - VERGE_OFFSET_M if board.side < 0 else edge_left_m + VERGE_OFFSET_M
        add_plate(spec, f"distractor_{k}_{board.kind}", shape, (board.x_m, y_m, 0.0), 0.0, SIGN_BOTTOM_M, texture)
