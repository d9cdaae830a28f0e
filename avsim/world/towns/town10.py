"""Town10: downtown. A wide avenue with a median, tall buildings, street clutter and other signs."""

from __future__ import annotations

import mujoco
import numpy as np

from avsim.world import props
from avsim.world.road import APPROACH_LENGTH_M, RoadLayout
from avsim.world.signs import PlacedSign
from avsim.world.towns.base import SIGHT_CORRIDOR_M, SIGHT_CORRIDOR_START_X_M, SIGN_BOTTOM_M, TOWNS, Town

LAYOUT = RoadLayout(lane_width_m=3.5, lanes_per_direction=3, median_width_m=2.0, sidewalk_width_m=5.0, cross_street_width_m=20.0)


def build(spec: mujoco.MjSpec, layout: RoadLayout, rng: np.random.Generator) -> list[PlacedSign]:
    """Town10's scenery along the approach road (world frame [m]); returns the non-target signs it placed."""
    half_w = layout.half_width_m
    cross0, cross1 = layout.cross_street_x_m
    right_front = min(layout.lane_edge_y_m - SIGHT_CORRIDOR_M - 1.0, -half_w - layout.sidewalk_width_m - 1.0)
    left_front = half_w + layout.sidewalk_width_m + 1.0
    for x0, x1 in ((-APPROACH_LENGTH_M, cross0 - 3), (cross1 + 3, 80.0)):
        props.add_building_row(spec, f"tower_right_{int(x0)}", rng, x0, x1, right_front, -1, (40, 90))
        props.add_building_row(spec, f"tower_left_{int(x0)}", rng, x0, x1, left_front, 1, (40, 90))
    kerb_r, kerb_l = -half_w - 0.7, half_w + 0.7
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M, 40, 25.0)):
        props.add_lamp_post(spec, f"lamp_left_{k}", float(x), kerb_l, -1)
        if x < SIGHT_CORRIDOR_START_X_M:
            props.add_lamp_post(spec, f"lamp_right_{k}", float(x), kerb_r, 1)
        props.add_lamp_post(spec, f"lamp_median_{k}", float(x) + 12, 0.0, 1)
    # Low clutter (below the camera's line of sight to a sign) may stand anywhere.
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M + 5, -5, 11.0)):
        props.add_bollard(spec, f"bollard_right_{k}", float(x), kerb_r)
        if rng.random() < 0.3:
            props.add_bin(spec, f"bin_right_{k}", float(x + 3), kerb_r - 1.5)
        if rng.random() < 0.3:
            props.add_bin(spec, f"bin_left_{k}", float(x + 5), kerb_l + 1.5)
    for k, x in enumerate(np.arange(-APPROACH_LENGTH_M + 20, cross0 - 20, 9.0)):
        if rng.random() < 0.6:
            props.add_parked_car(spec, f"parked_left_{k}", float(x), half_w - 1.1, np.pi, props.CAR_PAINTS[int(rng.integers(len(props.CAR_PAINTS)))])
    props.add_red_distractor(spec, "kiosk", -110.0, -half_w - 3.0, (2.0, 1.5, 2.6))
    props.add_red_distractor(spec, "postbox", -45.0, -half_w - 1.0, (0.5, 0.5, 1.1))
    edge = layout.lane_edge_y_m
    return [
        PlacedSign("sign_speed_limit_0", "speed_limit", (-190.0, edge - 2.0, 0.0), 0.0, SIGN_BOTTOM_M),
        PlacedSign("sign_yield_0", "yield", (-120.0, edge - 3.0, 0.0), 0.0, SIGN_BOTTOM_M),
        PlacedSign("sign_speed_limit_1", "speed_limit", (-80.0, half_w + 1.5, 0.0), 0.0, SIGN_BOTTOM_M),
    ]


TOWNS.add("town10", Town("town10", "downtown avenue, tall buildings, street clutter, other signs", LAYOUT, "plaza", build))
