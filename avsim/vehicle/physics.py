"""Named readouts and actuation of the ego car in a compiled scene.

World frame as in `avsim.world.road` (x along the road, y left, z up). Car body
frame: x forward, origin midway between the axles at wheel-centre height
(see models/car.xml).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.config import VehicleConfig

GRAVITY_MPS2 = 9.81
WHEELS = ("fl", "fr", "rl", "rr")
FRONT_BUMPER_X_M = 2.30  # body-frame x of the front bumper (models/car.xml)
WHEEL_RADIUS_M = 0.33
RIDE_HEIGHT_M = 0.33  # body origin above the road at rest


@dataclass(frozen=True)
class Controls:
    """One control step's commands: throttle and brake in [0, 1], steer [rad] (left +)."""

    throttle: float = 0.0
    brake: float = 0.0
    steer_rad: float = 0.0


class Vehicle:
    """The ego car inside `model`/`data` (joint and body names carry the `car/` prefix)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, config: VehicleConfig, prefix: str = "car/") -> None:
        self.model, self.data, self.config = model, data, config
        self._body = model.body(prefix + "car").id
        free = model.joint(prefix + "car_free")
        self._qpos = free.qposadr[0]
        self._qvel = free.dofadr[0]
        self._spin_dofs = np.array([model.joint(f"{prefix}spin_{w}").dofadr[0] for w in WHEELS])
        self._steer_act = [model.actuator(f"{prefix}steer_{w}").id for w in ("fl", "fr")]
        self._drive_act = [model.actuator(f"{prefix}drive_{w}").id for w in ("rl", "rr")]
        self.mass_kg = float(model.body_subtreemass[self._body])
        # Rolling resistance is a constant opposing torque at each wheel: C_rr * (m g / 4) * r.
        self._rolling_torque_nm = config.rolling_resistance_coeff * self.mass_kg * GRAVITY_MPS2 / 4 * WHEEL_RADIUS_M
        self._max_brake_nm = np.array([config.max_brake_torque_front_nm] * 2 + [config.max_brake_torque_rear_nm] * 2)

    # ---- state --------------------------------------------------------------------
    def place(self, x_m: float, y_m: float, yaw_rad: float, speed_mps: float) -> None:
        """Put the car on the road at body-origin (x, y), heading yaw, rolling at speed."""
        q = self.data.qpos
        q[self._qpos: self._qpos + 3] = (x_m, y_m, RIDE_HEIGHT_M)
        q[self._qpos + 3: self._qpos + 7] = (math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2))
        v = self.data.qvel
        v[self._qvel: self._qvel + 6] = 0.0
        v[self._qvel] = speed_mps * math.cos(yaw_rad)
        v[self._qvel + 1] = speed_mps * math.sin(yaw_rad)
        v[self._spin_dofs] = speed_mps / WHEEL_RADIUS_M
        mujoco.mj_forward(self.model, self.data)

    def position_xy_m(self) -> np.ndarray:
        """Body origin in the world, (2,) [m]."""
        return self.data.qpos[self._qpos: self._qpos + 2].copy()

    def yaw_rad(self) -> float:
        w, x, y, z = self.data.qpos[self._qpos + 3: self._qpos + 7]
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    def velocity_world_mps(self) -> np.ndarray:
        """Linear velocity of the body origin in the world, (3,) [m/s]."""
        return self.data.qvel[self._qvel: self._qvel + 3].copy()

    def speed_mps(self) -> float:
        """Forward speed along the car's heading [m/s] (negative when rolling back)."""
        yaw = self.yaw_rad()
        v = self.data.qvel
        return float(v[self._qvel] * math.cos(yaw) + v[self._qvel + 1] * math.sin(yaw))

    def lateral_speed_mps(self) -> float:
        yaw = self.yaw_rad()
        v = self.data.qvel
        return float(-v[self._qvel] * math.sin(yaw) + v[self._qvel + 1] * math.cos(yaw))

    def front_bumper_xy_m(self) -> np.ndarray:
        yaw = self.yaw_rad()
        return self.position_xy_m() + FRONT_BUMPER_X_M * np.array([math.cos(yaw), math.sin(yaw)])

    def is_finite(self) -> bool:
        return bool(np.isfinite(self.data.qpos).all() and np.isfinite(self.data.qvel).all())

    # ---- actuation ------------------------------------------------------------------
    def apply(self, controls: Controls) -> None:
        """Set drive torque, brake friction and steering for the coming physics steps."""
        drive_nm = controls.throttle * self.config.max_drive_torque_nm
        self.data.ctrl[self._drive_act] = drive_nm
        self.data.ctrl[self._steer_act] = controls.steer_rad
        # The brake is a friction torque on each wheel joint: it does not fade as the
        # wheel slows, and it holds the car still once stopped.
        self.model.dof_frictionloss[self._spin_dofs] = self._rolling_torque_nm + controls.brake * self._max_brake_nm
        self._apply_drag()

    def _apply_drag(self) -> None:
        """Aerodynamic drag 0.5 rho CdA |v| v on the body, held for the control step."""
        v = self.velocity_world_mps()
        v[2] = 0.0
        k = 0.5 * self.config.air_density_kgpm3 * self.config.drag_area_m2
        self.data.xfrc_applied[self._body, :3] = -k * np.linalg.norm(v) * v
