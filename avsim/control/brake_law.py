"""The study's brake law: the constant deceleration v^2/2d that stops within a distance, and the brake
command that asks for it. The pinhole range it is fed with is `avsim.sensors.pinhole`."""

from __future__ import annotations


def required_decel_mps2(speed_mps: float, stop_dist_m: float) -> float:
    """Constant deceleration that stops from `speed_mps` within `stop_dist_m`: a = v^2 / (2 d).

    A non-positive distance (already at or past the target) asks for unbounded braking.
    """
    if stop_dist_m <= 0:
        return float("inf")
    return speed_mps * speed_mps / (2.0 * stop_dist_m)


def brake_command(decel_mps2: float, a_max_mps2: float, multiplier: float) -> float:
    """b = min(a / a_max * M, 1), in [0, 1]."""
    return min(max(decel_mps2 / a_max_mps2 * multiplier, 0.0), 1.0)
