"""Small statistics shared by the reports, with no heavy imports (the experiment report uses them)."""

from __future__ import annotations

import numpy as np


def wilson_interval(hits: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval (Wilson, JASA 1927) of a proportion hits / n; (nan, nan) for n = 0.

    Unlike the normal approximation it stays inside [0, 1] and is sensible at 0 or n hits,
    which is where a recall near 1 lives.
    """
    if n == 0:
        return float("nan"), float("nan")
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))
