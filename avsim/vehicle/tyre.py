"""The tyre's friction against its longitudinal slip: a peak, then the lower sliding friction.

MuJoCo's contact friction is Coulomb: one coefficient, the same whether the tyre grips or
slides. A real tyre's friction peaks at a small slip (about 10-20 %) and falls as the wheel
locks; that drop is why anti-lock brakes stop a car sooner than locked wheels. avsim keeps
MuJoCo's contact and sets each tyre-road pair's coefficient every physics step from the
wheel's current slip:

    mu(slip) = road_mu                                  for |slip| <= peak_slip
    mu(slip) = road_mu * (1 - (1 - sliding_ratio) * (|slip| - peak_slip) / (1 - peak_slip))  above

so a locked wheel (|slip| = 1) slides at sliding_ratio * road_mu. Below the peak the contact
sticks (with MuJoCo's small soft-contact creep), so the curve is flat there: the grip a
tyre can give, not the force it gives. The shape loosely follows measured dry-asphalt
curves (Burckhardt's model: peak near 15 % slip, a locked wheel at about 0.65-0.8 of the
peak); road_mu is the peak, the figure quoted for a surface (dry 0.9, wet 0.5-0.6, snow 0.2).
"""

from __future__ import annotations

import numpy as np

# Below this hub speed [m/s] a slip ratio is dominated by contact creep and noise; the
# ratio's denominator is held at this floor, so a crawling wheel reads as rolling.
SLIP_SPEED_FLOOR_MPS = 1.0


def slip_ratios(hub_speed_mps: np.ndarray, wheel_surface_speed_mps: np.ndarray,
                speed_floor_mps: float = SLIP_SPEED_FLOOR_MPS) -> np.ndarray:
    """Longitudinal slip per wheel, (4,): (v_hub - omega r) / max(|v_hub|, floor).

    Positive under braking (the tyre's surface is slower than the ground), negative under
    wheelspin, 1 for a locked wheel on a moving car. hub_speed_mps: the hub's velocity along
    the wheel's heading [m/s]; wheel_surface_speed_mps: spin rate times radius [m/s].
    """
    return (hub_speed_mps - wheel_surface_speed_mps) / np.maximum(np.abs(hub_speed_mps), speed_floor_mps)


def friction_coefficients(road_mu: float, slip: np.ndarray, peak_slip: float, sliding_ratio: float) -> np.ndarray:
    """Tyre-road friction coefficient per wheel for its slip, (4,) (see the module docstring)."""
    beyond = np.clip((np.abs(slip) - peak_slip) / (1.0 - peak_slip), 0.0, 1.0)
    return road_mu * (1.0 - (1.0 - sliding_ratio) * beyond)
