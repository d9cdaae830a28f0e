"""The front camera's running estimate of the distance to the stop line, as `adjusted` keeps it.

Shared by the policies that brake by the v^2 / 2d law on a camera estimate (`adjusted`,
`combined`, `map_prior`).
"""

from __future__ import annotations

from avsim.perception.base import Detection


class DeadReckonedEstimate:
    """Bumper-to-stop-line distance [m], updated once per control step.

    - A gated detection whose box spans the whole sign (not truncated by the image border)
      gives a measurement;
    - otherwise (the sign left the view, at about 10 m, or the box is cut) the last estimate is
      carried forward by odometry: speed times the control period;
    - the estimate never grows: a box that puts the sign farther away than odometry allows
      (the car only moves towards it) is not believed, and the estimate is the smaller of the
      two. A learned detector's boxes of a near, partly hidden sign come out short, and
      believing them would release the brake at the worst moment.
    """

    def __init__(self, control_dt_s: float) -> None:
        self.control_dt_s = control_dt_s
        self.estimate_m: float | None = None

    def update(self, gated: tuple[Detection, float] | None, speed_mps: float) -> float | None:
        """gated: this step's (detection, its stop-line estimate [m]) through the braking gate, or None."""
        dead_reckoned = None if self.estimate_m is None else self.estimate_m - speed_mps * self.control_dt_s
        if gated is not None and not gated[0].truncated:
            measured = gated[1]
            self.estimate_m = measured if dead_reckoned is None else min(measured, dead_reckoned)
        else:
            self.estimate_m = dead_reckoned
        return self.estimate_m
