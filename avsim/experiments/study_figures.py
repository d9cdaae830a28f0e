"""The study's published figures, keyed by the cell names of avsim's experiment files.

Source: the study in `../shared/paper/` (CARLA 0.9.x, YOLOv8x, 85 km/h), as summarised in
`../shared/REFERENCE.md`: Table III (stop positions in Town07, standard placement), Tables I
and II (both defences on: time from the start of braking to a full stop, and distance to
the sign when the brake came on) and Fig. 3 (detection confidence of the clean and the five
attacked signs). Facts only; avsim measures its own and the report sets them side by side.

Distances "before the sign" are the study's: along the road from the car's position (CARLA's
actor origin, the middle of the car) to the sign post; positive before the sign.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StopPosition:
    """A Table III row: where the car stopped [m] (CARLA world frame) and how far before the sign."""

    stop_xy_m: tuple[float, float]
    before_sign_m: float  # negative: past the sign


@dataclass(frozen=True)
class DefendedStop:
    """A Table I or II row: time from the first brake to a full stop [s] and distance to the sign
    when the brake came on [m]."""

    time_to_stop_s: float
    dist_at_brake_m: float


# Table III: Town07 standard. The sign stands at (-9.3, -50.5); the car drives toward -y.
SIGN_XY_M = (-9.3, -50.5)
TABLE3: dict[str, StopPosition] = {
    "clean sign, baseline": StopPosition((-5.4, -46.2), 4.3),
    "attacked sign, baseline": StopPosition((-5.4, -60.8), -10.3),
    "attacked sign, adjusted": StopPosition((-5.4, -43.5), 7.0),
    "attacked sign, side_camera": StopPosition((-5.4, -47.5), 3.0),
    "autopilot": StopPosition((-5.9, -44.5), 6.0),
}

# Table I (clean sign) and Table II (attacked sign), both defences on.
TABLE1: dict[str, DefendedStop] = {
    "Town07 standard": DefendedStop(2.70, 39.12),
    "Town03 far": DefendedStop(2.60, 35.95),
    "Town03 near": DefendedStop(2.71, 33.26),
    "Town10 far": DefendedStop(2.75, 39.12),
    "Town10 near": DefendedStop(2.75, 39.12),
}
TABLE2: dict[str, DefendedStop] = {
    "Town07 standard": DefendedStop(2.70, 38.01),
    "Town03 far": DefendedStop(2.55, 25.58),
    "Town03 near": DefendedStop(2.75, 35.01),
    "Town10 far": DefendedStop(2.70, 35.01),
    "Town10 near": DefendedStop(2.70, 35.01),
}

# Fig. 3: YOLOv8x's confidence on the clean sign; every attacked sign scored lower, Lu v2 lowest.
CLEAN_CONFIDENCE = 0.75
LOWEST_CONFIDENCE_ATTACK = "lu_v2"
