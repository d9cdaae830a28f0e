"""Small statistics every report shares."""

from __future__ import annotations

import math


def wilson_interval(hits: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval (Wilson, JASA 1927) of a proportion hits / n; (nan, nan) for n = 0.

    Unlike the normal approximation it stays inside [0, 1] and is sensible at 0 or n hits,
    which is where a recall near 1, or a stop rate of 5 of 5, lives. z = 1.96: 95 %.
    """
    if n == 0:
        return float("nan"), float("nan")
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # At 0 or n hits a bound is exactly 0 or 1; computed, it can miss by an ulp (6/6 gave 1 - 1e-16),
    # which put the point estimate outside its own interval.
    low = 0.0 if hits == 0 else max(0.0, centre - half)
    high = 1.0 if hits == n else min(1.0, centre + half)
    return low, high


def rate_with_interval(hits: int, n: int) -> str:
    """"k/n (lo–hi)": a rate with its Wilson 95 % interval, for tables."""
    if n == 0:
        return "–"
    lo, hi = wilson_interval(hits, n)
    return f"{hits}/{n} ({lo:.2f}–{hi:.2f})"


def sign_test_p(gained: int, lost: int) -> float:
    """Exact two-sided sign test (binomial, p = 1/2) of paired outcomes that changed: `gained` went one
    way and `lost` the other; the pairs that did not change carry no information and are left out.
    1.0 when nothing changed."""
    changed = gained + lost
    if changed == 0:
        return 1.0
    tail = sum(math.comb(changed, k) for k in range(min(gained, lost) + 1)) / 2 ** changed
    return min(1.0, 2 * tail)
