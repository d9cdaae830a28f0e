"""The study's defence-1 arithmetic: pinhole range from a box height, and the v^2/2d brake law."""

from __future__ import annotations


def pinhole_distance_m(sign_height_m: float, f_px: float, box_height_px: float) -> float:
    """Depth of a sign along the optical axis: d = H_real * f / h_bbox [m].

    f_px = H_img / (2 tan(fovy / 2)) is the focal length in pixels.
    """
    if box_height_px <= 0:
        raise ValueError(f"box height must be positive, got {box_height_px}")
    return sign_height_m * f_px / box_height_px


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
