"""Longitudinal cruise control and lane keeping (both used until a policy brakes)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class SpeedController:
    """PI controller from speed error [m/s] to throttle in [0, 1], with anti-windup.

    Gains are per (m/s): full throttle for a 2 m/s shortfall; the integral holds
    the throttle that balances drag and rolling resistance at cruise.
    """

    target_mps: float
    kp_per_mps: float = 0.5
    ki_per_m: float = 0.15
    _integral: float = field(default=0.0, repr=False)

    def throttle(self, speed_mps: float, dt_s: float) -> float:
        """Throttle in [0, 1] for this control step of `dt_s` [s] towards `target_mps` from `speed_mps`
        (PI, integrating only while the output is not saturated in the error's direction).
        """
        error = self.target_mps - speed_mps
        unclamped = self.kp_per_mps * error + self.ki_per_m * self._integral
        # Integrate only while the output is not saturated in the error's direction.
        if 0.0 < unclamped < 1.0 or (unclamped >= 1.0 and error < 0) or (unclamped <= 0.0 and error > 0):
            self._integral += error * dt_s
        return min(max(self.kp_per_mps * error + self.ki_per_m * self._integral, 0.0), 1.0)


@dataclass(frozen=True)
class LaneKeeper:
    """Stanley lateral controller for a straight lane along world +x at `lane_y_m`.

    steer = -heading error - atan(k * cross-track error / (speed + softening)).
    """

    lane_y_m: float
    gain: float = 1.0
    softening_mps: float = 1.0
    max_steer_rad: float = 0.5

    def steer_rad(self, y_m: float, yaw_rad: float, speed_mps: float) -> float:
        """Steering angle [rad], clamped to +-`max_steer_rad`, positive to the left, from the car's lateral
        position `y_m` (world frame [m]), heading `yaw_rad` and speed (a Stanley-style lane keeper).
        """
        cross_track_m = y_m - self.lane_y_m  # positive: left of the lane centre
        steer = -yaw_rad - math.atan2(self.gain * cross_track_m, max(speed_mps, 0.0) + self.softening_mps)
        return min(max(steer, -self.max_steer_rad), self.max_steer_rad)
