"""The approach road every town shares: lanes, markings, stop line and cross street.

World frame: x along the road in the direction of travel, y to the left, z up [m].
Traffic keeps right, so the car's lane is the right-most lane of the +x direction
(y < 0). The stop line's near edge is at x = 0; the approach road starts at
x = -APPROACH_LENGTH_M.

Layering (heights of top surfaces): visual ground -0.05 m, asphalt 0.0 m (the
physical contact plane is also at 0), paint +0.01 m. The gaps are larger than the
depth-buffer resolution at 300 m, so distant markings do not flicker.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

APPROACH_LENGTH_M = 320.0
ROAD_END_X_M = 60.0  # the road continues past the intersection
STOP_LINE_X_M = 0.0
STOP_LINE_WIDTH_M = 0.45
PAINT_Z_M = 0.01
DASH_LENGTH_M, DASH_PERIOD_M = 3.0, 9.0
DASHED_LENGTH_M = 150.0  # lane dividers are painted this far back from the stop line
BOX = mujoco.mjtGeom.mjGEOM_BOX


@dataclass(frozen=True)
class RoadLayout:
    """Cross-section of a town's road [m]. Lanes are symmetric about y = median centre (0)."""

    lane_width_m: float
    lanes_per_direction: int
    median_width_m: float
    sidewalk_width_m: float  # 0 for a rural road with a gravel shoulder
    cross_street_width_m: float

    @property
    def lane_edge_y_m(self) -> float:
        """Right edge of the travelled (right-most) lane; signs are placed from here."""
        return -(self.median_width_m / 2 + self.lanes_per_direction * self.lane_width_m)

    @property
    def lane_center_y_m(self) -> float:
        """Lateral position of the ego lane's centre line, world y [m] (negative: traffic keeps right)."""
        return self.lane_edge_y_m + self.lane_width_m / 2

    @property
    def half_width_m(self) -> float:
        """Half the carriageway, kerb to kerb."""
        return -self.lane_edge_y_m + 0.5

    @property
    def cross_street_x_m(self) -> tuple[float, float]:
        """x range of the cross street; a crosswalk's width separates it from the stop line."""
        start = STOP_LINE_X_M + STOP_LINE_WIDTH_M + 3.0
        return start, start + self.cross_street_width_m


def _box(spec: mujoco.MjSpec, name: str, centre: tuple[float, float, float], half: tuple[float, float, float], material: str) -> None:
    spec.worldbody.add_geom(name=name, type=BOX, pos=list(centre), size=list(half), material=material,
                            contype=0, conaffinity=0)


def add_road(spec: mujoco.MjSpec, layout: RoadLayout, stop_line: bool = True) -> None:
    """Add asphalt, lane paint, stop line (unless `stop_line` is false), sidewalks and a cross
    street to `spec`.

    Expects the materials of `avsim.world.props.add_materials`.
    """
    length = APPROACH_LENGTH_M + ROAD_END_X_M
    mid_x = (ROAD_END_X_M - APPROACH_LENGTH_M) / 2
    half_w = layout.half_width_m
    _box(spec, "road/asphalt", (mid_x, 0, -0.025), (length / 2, half_w, 0.025), "asphalt")
    cx0, cx1 = layout.cross_street_x_m
    _box(spec, "road/cross_street", ((cx0 + cx1) / 2, 0, -0.02), ((cx1 - cx0) / 2, 200, 0.02), "asphalt")

    # Lane lines on the approach only (they stop at the stop line, as painted).
    lw = layout.lane_width_m
    for side in (-1, 1):
        base = side * layout.median_width_m / 2
        # Centre line (yellow) or median edge.
        _box(spec, f"road/centre_line_{side}", ((STOP_LINE_X_M - APPROACH_LENGTH_M) / 2, base - side * 0.1 if layout.median_width_m else side * 0.1,
             PAINT_Z_M / 2), (APPROACH_LENGTH_M / 2, 0.06, PAINT_Z_M / 2), "paint_yellow")
        # Edge line.
        edge_y = side * (layout.median_width_m / 2 + layout.lanes_per_direction * lw)
        _box(spec, f"road/edge_line_{side}", ((STOP_LINE_X_M - APPROACH_LENGTH_M) / 2, edge_y - side * 0.1, PAINT_Z_M / 2),
             (APPROACH_LENGTH_M / 2, 0.075, PAINT_Z_M / 2), "paint_white")
        for lane in range(1, layout.lanes_per_direction):
            # Dashes only where a camera can resolve them: each is a draw call.
            y = side * (layout.median_width_m / 2 + lane * lw)
            for k, x in enumerate(np.arange(STOP_LINE_X_M - 10.0, STOP_LINE_X_M - DASHED_LENGTH_M, -DASH_PERIOD_M)):
                _box(spec, f"road/dash_{side}_{lane}_{k}", (x - DASH_LENGTH_M / 2, y, PAINT_Z_M / 2),
                     (DASH_LENGTH_M / 2, 0.075, PAINT_Z_M / 2), "paint_white")
    if layout.median_width_m:
        _box(spec, "road/median", ((STOP_LINE_X_M - 12 - APPROACH_LENGTH_M) / 2, 0, 0.075),
             ((APPROACH_LENGTH_M - 12) / 2, layout.median_width_m / 2 - 0.3, 0.075), "kerb")

    # Stop line across the travelled direction's lanes only.
    lanes_w = layout.lanes_per_direction * lw
    if stop_line:
        _box(spec, "road/stop_line", (STOP_LINE_X_M + STOP_LINE_WIDTH_M / 2, -(layout.median_width_m / 2 + lanes_w / 2), PAINT_Z_M / 2),
             (STOP_LINE_WIDTH_M / 2, lanes_w / 2, PAINT_Z_M / 2), "paint_white")
    # Crosswalk bars between the stop line and the cross street.
    for k, y in enumerate(range(int(-half_w) + 1, int(half_w), 2)):
        _box(spec, f"road/crosswalk_{k}", (STOP_LINE_X_M + STOP_LINE_WIDTH_M + 1.5, y + 0.5, PAINT_Z_M / 2), (1.2, 0.4, PAINT_Z_M / 2), "paint_white")

    if layout.sidewalk_width_m:
        for side in (-1, 1):
            y = side * (half_w + layout.sidewalk_width_m / 2)
            for name, x0, x1 in (("approach", -APPROACH_LENGTH_M, cx0), ("beyond", cx1, ROAD_END_X_M)):
                _box(spec, f"road/sidewalk_{side}_{name}", ((x0 + x1) / 2, y, 0.075),
                     ((x1 - x0) / 2, layout.sidewalk_width_m / 2, 0.075), "sidewalk")
