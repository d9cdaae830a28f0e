"""Town03: urban. Four lanes, sidewalks, mid-rise buildings and parked cars."""

from __future__ import annotations

import mujoco
import numpy as np

from avsim.world import props
from avsim.world.road import APPROACH_LENGTH_M, RoadLayout
from avsim.world.signs import PlacedSign
from avsim.world.towns.base import SIGHT_CORRIDOR_M, SIGHT_CORRIDOR_START_X_M, SIGN_BOTTOM_M, TOWNS, Town

LAYOUT = RoadLayout(lane_width_m=3.5, lanes_per_direction=2, median_width_m=0.0, sidewalk_width_m=3.0, cross_street_width_m=14.0)


def build(spec: mujoco.MjSpec, layout: RoadLayout, rng: np.random.Generator) -> list[PlacedSign]:
    """Town03's scenery along the approach road (world frame [m]): building rows, parked cars and
    street furniture; returns the non-target signs it placed.
    """
    half_w = layout.half_width_m
    cross0, cross1 = layout.cross_street_x_m
    right_front = layout.lane_edge_y_m - SIGHT_CORRIDOR_M - 1.0
    left_front = half_w + layout.sidewalk_width_m + 1.0
    for x0, x1 in ((-APPROACH_LENGTH_M, cross0 - 3), (cross1 + 3, 60.0)):
        props.add_building_row(spec, f"bldg_right_{int(x0)}", rng, x0, x1, right_front, -1, (12, 30))
        props.add_building_row(spec, f"bldg_left_{int(x0)}", rng, x0, x1, left_front, 1, (12, 30))
    # Parked cars along the far kerb, and a few on the near kerb well before the junction.
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M + 10, cross0 - 15, 7.5)):
        if rng.random() < 0.7:
            props.add_parked_car(spec, f"parked_left_{k}", float(x), half_w - 1.1, np.pi, props.CAR_PAINTS[int(rng.integers(len(props.CAR_PAINTS)))])
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M + 10, SIGHT_CORRIDOR_START_X_M - 20, 9.0)):
        if rng.random() < 0.5:
            props.add_parked_car(spec, f"parked_right_{k}", float(x), -half_w - layout.sidewalk_width_m - 2.0, 0.0, props.CAR_PAINTS[int(rng.integers(len(props.CAR_PAINTS)))])
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M, 40, 30.0)):
        props.add_lamp_post(spec, f"lamp_left_{k}", float(x), half_w + 0.6, -1)
        if x < SIGHT_CORRIDOR_START_X_M:
            props.add_lamp_post(spec, f"lamp_right_{k}", float(x), -half_w - 0.6, 1)
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M + 15, 0, 40.0)):
        props.add_tree(spec, f"street_tree_{k}", float(x), half_w + 2.0, float(rng.uniform(5, 7)))
    props.add_red_distractor(spec, "postbox", -35.0, -half_w - 1.2, (0.5, 0.5, 1.1))
    speed = PlacedSign("sign_speed_limit_0", "speed_limit", (-140.0, layout.lane_edge_y_m - 2.0, 0.0), 0.0, SIGN_BOTTOM_M)
    return [speed]


TOWNS.add("town03", Town("town03", "urban four-lane street, sidewalks, mid-rise buildings, parked cars", LAYOUT, "plaza", build))
