"""Anti-lock brakes (and the same controller as traction control): a per-wheel slip limiter.

It runs at the physics rate on the simulated wheel state: each step it reads every wheel's
longitudinal slip and decides how much of the requested torque reaches the wheel. The
logic is the classic pressure-modulation cycle of a hydraulic ABS:

- **release**: when a wheel's slip passes `target_slip`, its torque limit drops to
  `RELEASE_FACTOR` of the torque it had, every step until the slip is back under the target;
- **fast re-apply**: below the target the limit climbs quickly back to `HOLD_FRACTION` of the
  torque at which the wheel last began to slip (the grip the road gave then);
- **slow probe**: above that, it climbs slowly, probing for more grip (load moves between the
  axles as the body pitches, and the road may change).

Nothing in it knows the road's friction or the wheel's load: it acts only on measured slip.
The resulting efficiency (mean deceleration over mu g) is measured, not assumed:
`avsim.vehicle.brake_test`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RELEASE_FACTOR = 0.85  # of the applied torque, per physics step while over the target slip
HOLD_FRACTION = 0.95  # of the torque at the last slip onset: where fast re-apply stops
FAST_REAPPLY_PER_S = 8.0  # in units of the requested torque per second
SLOW_REAPPLY_PER_S = 0.5
# The slip ratio the controller reads uses at least this speed as its denominator [m/s]: at a
# crawl, contact creep of a few cm/s would read as a large slip and release the brake.
CONTROL_SPEED_FLOOR_MPS = 3.0
# Below this hub speed [m/s] the controller lets the full torque through, as real units
# switch off near standstill so the brake can hold the car.
MIN_ACTIVE_SPEED_MPS = 1.0


@dataclass
class SlipLimiter:
    """Per-wheel torque limits that keep each wheel's slip near `target_slip`.

    For anti-lock braking, slip is the braking slip (positive when the wheel is slower than
    the ground); for traction control, pass the negated slip of the driven wheels.
    """

    target_slip: float
    wheels: int = 4

    def __post_init__(self) -> None:
        self.limit_nm = np.full(self.wheels, np.inf)  # torque allowed through [N m]
        self._onset_nm = np.full(self.wheels, np.inf)  # torque when the wheel last began to slip
        self._slipping = np.zeros(self.wheels, dtype=bool)

    @property
    def active(self) -> bool:
        """Whether any wheel's torque is being limited (or a slip is being watched)."""
        return bool(np.isfinite(self.limit_nm).any() or self._slipping.any())

    def reset(self) -> None:
        """Forget every limit: the next request passes in full."""
        self.limit_nm[:] = np.inf
        self._onset_nm[:] = np.inf
        self._slipping[:] = False

    def limit(self, requested_nm: np.ndarray, applied_nm: np.ndarray, slip: np.ndarray, hub_speed_mps: np.ndarray,
              dt_s: float) -> np.ndarray:
        """Torque per wheel to apply for the next physics step, (wheels,) [N m].

        requested_nm: what the driver or policy asks for; applied_nm: what the wheels got in the
        last step; slip: the slip ratios as in `avsim.vehicle.tyre.slip_ratios` but with the
        denominator floored at `CONTROL_SPEED_FLOOR_MPS`; hub_speed_mps: the hubs' speed [m/s].
        """
        slipping = slip > self.target_slip
        onset = slipping & ~self._slipping
        self._onset_nm = np.where(onset, applied_nm, self._onset_nm)
        below_hold = self.limit_nm < HOLD_FRACTION * self._onset_nm
        rate_per_s = np.where(below_hold, FAST_REAPPLY_PER_S, SLOW_REAPPLY_PER_S)
        released = np.minimum(self.limit_nm, applied_nm) * RELEASE_FACTOR
        reapplied = np.minimum(self.limit_nm, requested_nm) + requested_nm * rate_per_s * dt_s
        self.limit_nm = np.where(slipping, released, reapplied)
        inactive = np.abs(hub_speed_mps) < MIN_ACTIVE_SPEED_MPS
        self.limit_nm = np.where(inactive, np.inf, self.limit_nm)
        self._slipping = slipping & ~inactive
        return np.minimum(requested_nm, self.limit_nm)
