"""Range from a pinhole camera: how far a sign of known size stands, from its box height in pixels.

Shared by perception (the range estimate beside each detection) and control (the study's
defence 1, adjusted braking), which is why it lives with the sensors both of them sit above.
"""

from __future__ import annotations


def pinhole_distance_m(sign_height_m: float, f_px: float, box_height_px: float) -> float:
    """Depth of a sign along the optical axis: d = H_real * f / h_bbox [m].

    f_px = H_img / (2 tan(fovy / 2)) is the focal length in pixels.
    """
    if box_height_px <= 0:
        raise ValueError(f"box height must be positive, got {box_height_px}")
    return sign_height_m * f_px / box_height_px
