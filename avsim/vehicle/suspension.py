"""Spring, damper and preload of each wheel's suspension travel, from a ride frequency.

models/car.xml hangs every wheel from the body on a vertical slide joint `susp_<wheel>`
(q > 0: the hub moves up relative to the body, the spring compresses). Rather than fixing
stiffnesses in the XML, avsim derives them from the two numbers a ride engineer specifies,
the body's bounce frequency and damping ratio, and the masses in the model:

    m_c = sprung mass carried by the corner (static axle load share / 2)      [kg]
    k   = m_c (2 pi f)^2                                                       [N/m]
    c   = 2 zeta sqrt(k m_c)                                                   [N s/m]
    springref = -m_c g / k   (the spring's free position: at q = 0 it carries m_c g)

so every corner has the same undamped frequency f, and the body sits at the model's ride
height at rest. The static sag, from the spring's free length to rest, is m_c g / k =
g / (2 pi f)^2 at every corner: 0.127 m at 1.4 Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco

GRAVITY_MPS2 = 9.81
WHEELS = ("fl", "fr", "rl", "rr")


@dataclass(frozen=True)
class CornerSpring:
    """One corner's suspension: stiffness [N/m], damping [N s/m], spring free position [m]
    and the sprung mass it carries at rest [kg]."""

    stiffness_npm: float
    damping_nspm: float
    springref_m: float
    sprung_mass_kg: float

    @property
    def static_sag_m(self) -> float:
        """Compression of the spring from its free length at rest [m]."""
        return self.sprung_mass_kg * GRAVITY_MPS2 / self.stiffness_npm


def corner_springs(car: mujoco.MjSpec, frequency_hz: float, damping_ratio: float) -> dict[str, CornerSpring]:
    """Springs for each corner of the car spec (`models/car.xml`), keyed by wheel name.

    The sprung mass is the `car` body's own mass (the chassis); its centre of mass and the
    hubs' x positions split it between the axles, as a static balance of moments does.
    """
    compiled = car.compile()
    body = compiled.body("car")
    sprung_kg = float(compiled.body_mass[body.id])
    cg_x_m = float(compiled.body_ipos[body.id][0])
    front_x_m = float(compiled.body("hub_fl").pos[0])
    rear_x_m = float(compiled.body("hub_rl").pos[0])
    wheelbase_m = front_x_m - rear_x_m
    front_share = (cg_x_m - rear_x_m) / wheelbase_m  # moments about the rear axle
    omega = 2 * math.pi * frequency_hz
    springs = {}
    for wheel in WHEELS:
        corner_kg = sprung_kg * (front_share if wheel.startswith("f") else 1 - front_share) / 2
        stiffness = corner_kg * omega**2
        springs[wheel] = CornerSpring(
            stiffness_npm=stiffness,
            damping_nspm=2 * damping_ratio * math.sqrt(stiffness * corner_kg),
            springref_m=-corner_kg * GRAVITY_MPS2 / stiffness,
            sprung_mass_kg=corner_kg,
        )
    return springs


def apply_springs(car: mujoco.MjSpec, springs: dict[str, CornerSpring]) -> None:
    """Set the stiffness, damping and spring reference of each `susp_<wheel>` joint."""
    for wheel, spring in springs.items():
        joint = car.joint(f"susp_{wheel}")
        # MuJoCo 4 takes stiffness and damping as polynomial coefficients [linear, quadratic, cubic].
        joint.stiffness = [spring.stiffness_npm, 0.0, 0.0]
        joint.damping = [spring.damping_nspm, 0.0, 0.0]
        joint.springref = spring.springref_m
