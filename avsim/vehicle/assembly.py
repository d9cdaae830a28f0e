"""The car as MuJoCo needs it in a scene: suspension tuned, wheel-speed sensors, tyre-road contacts.

`load_car` reads models/car.xml and completes it from the vehicle config; `add_tyre_contacts`
adds one explicit contact pair per tyre with the road's contact geom. The tyres collide with
nothing else (their contype/conaffinity are 0), so those pairs are the car's only contacts,
and their friction is the road's: `avsim.vehicle.physics.Vehicle` reads it back as the peak
coefficient and scales it every physics step by the tyre's slip curve.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from avsim.config import VehicleConfig
from avsim.vehicle.suspension import WHEELS, apply_springs, corner_springs

CAR_XML = Path(__file__).resolve().parents[2] / "models" / "car.xml"
CAR_PREFIX = "car/"
# Torsional and rolling friction of a tyre contact (condim 3 uses only the sliding pair).
_SPIN_FRICTION, _ROLL_FRICTION = 0.005, 0.0001


def load_car(vehicle: VehicleConfig) -> mujoco.MjSpec:
    """models/car.xml with its springs set from the config and a hub-velocity sensor per wheel.

    Each sensor is a velocimeter on a site that turns with the wheel's heading (the steering
    knuckle in front, the hub at the rear), so its x reading is the hub's longitudinal speed.
    """
    car = mujoco.MjSpec.from_file(str(CAR_XML))
    apply_springs(car, corner_springs(car, vehicle.suspension_frequency_hz, vehicle.suspension_damping_ratio))
    for wheel in WHEELS:
        mount = car.body(f"steer_{wheel}" if wheel.startswith("f") else f"hub_{wheel}")
        mount.add_site(name=f"hub_{wheel}")
        car.add_sensor(name=f"hub_velocity_{wheel}", type=mujoco.mjtSensor.mjSENS_VELOCIMETER,
                       objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"hub_{wheel}")
    for geom in car.geoms:
        if geom.name.startswith("tyre_"):
            geom.contype = geom.conaffinity = 0  # only the explicit tyre-road pairs touch the road
    return car


def add_tyre_contacts(spec: mujoco.MjSpec, road_geom: str, road_friction: float, prefix: str = CAR_PREFIX) -> None:
    """One contact pair `tyre_<wheel>` per tyre with `road_geom`, at the road's friction (the
    tyre's peak coefficient). Call after the car is attached under `prefix`."""
    for wheel in WHEELS:
        spec.add_pair(name=f"tyre_{wheel}", geomname1=f"{prefix}tyre_{wheel}", geomname2=road_geom, condim=3,
                      friction=[road_friction, road_friction, _SPIN_FRICTION, _ROLL_FRICTION, _ROLL_FRICTION])
