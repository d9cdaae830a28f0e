"""Town07: rural. A two-lane country road through fields, with barns and trees."""

from __future__ import annotations

import mujoco
import numpy as np

from avsim.world import props
from avsim.world.road import APPROACH_LENGTH_M, RoadLayout
from avsim.world.signs import PlacedSign
from avsim.world.towns.base import SIGHT_CORRIDOR_M, TOWNS, Town

LAYOUT = RoadLayout(lane_width_m=3.5, lanes_per_direction=1, median_width_m=0.0, sidewalk_width_m=0.0, cross_street_width_m=7.0)


def build(spec: mujoco.MjSpec, layout: RoadLayout, rng: np.random.Generator) -> list[PlacedSign]:
    """Town07's scenery along the approach road (world frame [m]); returns the non-target signs it placed."""
    edge = layout.lane_edge_y_m
    far_right = edge - SIGHT_CORRIDOR_M - 4.0
    crops = ("field_wheat", "field_green", "soil")
    for side, y0 in ((-1, far_right - 2), (1, layout.half_width_m + 12)):
        x = -APPROACH_LENGTH_M
        k = 0
        while x < 60:
            length = float(rng.uniform(40, 90))
            depth = float(rng.uniform(40, 80))
            props.add_field(spec, f"field_{side}_{k}", x + length / 2, y0 + side * depth / 2, (length - 2, depth), crops[int(rng.integers(len(crops)))])
            x += length
            k += 1
    for k, (x, y) in enumerate(((-170.0, far_right - 30), (-60.0, layout.half_width_m + 40), (35.0, far_right - 25))):
        props.add_barn(spec, f"barn_{k}", x + float(rng.uniform(-10, 10)), y, float(rng.uniform(0, np.pi)))
    # A hedge-row of trees on the left all along; on the right only well back from the road.
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M, 60, 14.0)):
        props.add_tree(spec, f"tree_left_{k}", float(x + rng.uniform(-4, 4)), layout.half_width_m + float(rng.uniform(5, 9)), float(rng.uniform(6, 11)))
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M, 60, 25.0)):
        props.add_tree(spec, f"tree_right_{k}", float(x + rng.uniform(-6, 6)), far_right + float(rng.uniform(-6, 0)), float(rng.uniform(7, 12)))
    return []


TOWNS.add("town07", Town("town07", "rural two-lane road, fields, barns, trees", LAYOUT, "grass", build))
