"""Named readouts and actuation of the ego car in a compiled scene, and its physics stepping.

World frame as in `avsim.world.road` (x along the road, y left, z up). Car body
frame: x forward, origin midway between the axles at wheel-centre height when the car
stands at rest (see models/car.xml).

What happens between two control steps (`Vehicle.advance`), at every physics step:

1. each wheel's longitudinal slip is read from the simulated state (hub velocity sensor
   and wheel spin rate);
2. each tyre-road contact gets its friction coefficient for that slip (`avsim.vehicle.tyre`);
3. the brake torque a wheel receives is the policy's request, limited by the anti-lock
   controller (`avsim.vehicle.antilock`) and by how fast the hydraulics build pressure;
   the drive torque is limited the same way by traction control;
4. MuJoCo steps once.

Brakes are joint friction: each wheel's `dof_frictionloss` is the rolling resistance plus the
applied brake torque, a torque that does not fade as the wheel slows and holds the car at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from avsim.config import VehicleConfig
from avsim.vehicle.antilock import CONTROL_SPEED_FLOOR_MPS, SlipLimiter
from avsim.vehicle.suspension import GRAVITY_MPS2, WHEELS
from avsim.vehicle.tyre import friction_coefficients, slip_ratios

FRONT_BUMPER_X_M = 2.30  # body-frame x of the front bumper (models/car.xml)
WHEEL_RADIUS_M = 0.33
RIDE_HEIGHT_M = 0.33  # body origin above the road at rest
# `max_brake_slip` counts a wheel's slip only while its hub moves faster than this [m/s]:
# near standstill a slip ratio divides by almost nothing.
SLIP_REPORT_MIN_SPEED_MPS = 5.0
_DRIVEN = np.array([2, 3])  # rear-wheel drive: rl, rr


@dataclass(frozen=True)
class Controls:
    """One control step's commands: throttle and brake in [0, 1], steer [rad] (left +)."""

    throttle: float = 0.0
    brake: float = 0.0
    steer_rad: float = 0.0


class Vehicle:
    """The ego car inside `model`/`data` (joint and body names carry the `car/` prefix).

    The road's friction is read from the model's tyre-road contact pairs (`tyre_<wheel>`),
    which the scene builds with the scenario's road friction as their peak coefficient.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, config: VehicleConfig, prefix: str = "car/") -> None:
        self.model, self.data, self.config = model, data, config
        self._body = model.body(prefix + "car").id
        free = model.joint(prefix + "car_free")
        self._qpos = free.qposadr[0]
        self._qvel = free.dofadr[0]
        self._spin_dofs = np.array([model.joint(f"{prefix}spin_{w}").dofadr[0] for w in WHEELS])
        self._susp_qpos = np.array([model.joint(f"{prefix}susp_{w}").qposadr[0] for w in WHEELS])
        self._susp_dofs = np.array([model.joint(f"{prefix}susp_{w}").dofadr[0] for w in WHEELS])
        self._hub_speed = np.array([model.sensor(f"{prefix}hub_velocity_{w}").adr[0] for w in WHEELS])  # x of a velocimeter
        self._pairs = np.array([model.pair(f"tyre_{w}").id for w in WHEELS])
        self._steer_act = [model.actuator(f"{prefix}steer_{w}").id for w in ("fl", "fr")]
        self._drive_act = np.array([model.actuator(f"{prefix}drive_{w}").id for w in ("rl", "rr")])
        self.road_mu = float(model.pair_friction[self._pairs[0], 0])
        self.mass_kg = float(model.body_subtreemass[self._body])
        # Rolling resistance is a constant opposing torque at each wheel: C_rr * (m g / 4) * r.
        self._rolling_torque_nm = config.rolling_resistance_coeff * self.mass_kg * GRAVITY_MPS2 / 4 * WHEEL_RADIUS_M
        # Brake torque per wheel at brake = 1: the total brake force is the car's weight times
        # brake_force_at_full_g, split between the axles by the brake balance.
        total_nm = config.brake_force_at_full_g * self.mass_kg * GRAVITY_MPS2 * WHEEL_RADIUS_M
        front = config.brake_balance_front
        self._full_brake_nm = total_nm * np.array([front / 2, front / 2, (1 - front) / 2, (1 - front) / 2])
        self._brake_rise_nm_per_s = self._full_brake_nm / config.brake_rise_time_s
        self._antilock = SlipLimiter(config.abs_target_slip)
        self._traction = SlipLimiter(config.abs_target_slip, wheels=len(_DRIVEN))
        self._brake_request_nm = np.zeros(4)
        self._brake_applied_nm = np.zeros(4)
        self._drive_request_nm = np.zeros(len(_DRIVEN))
        self._drive_applied_nm = np.zeros(len(_DRIVEN))
        self._tyres_at_peak = True  # every tyre-road pair at the road's own friction
        self.last_max_brake_slip: float | None = None

    # ---- state --------------------------------------------------------------------
    def place(self, x_m: float, y_m: float, yaw_rad: float, speed_mps: float, pitch_rad: float = 0.0) -> None:
        """Put the car on the road at body-origin (x, y), heading yaw, rolling at speed,
        with the suspension at its static ride height and the brakes released.

        pitch_rad: the body's pitch, positive nose down (as `pitch_rad()` reads it), for posing
        the cameras as the suspension tilts them under braking; 0 is level.
        """
        q = self.data.qpos
        q[self._qpos: self._qpos + 3] = (x_m, y_m, RIDE_HEIGHT_M)
        cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
        if pitch_rad == 0.0:
            q[self._qpos + 3: self._qpos + 7] = (cy, 0.0, 0.0, sy)
        else:  # yaw about the world z, then pitch about the body's own y axis: q_yaw * q_pitch
            cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
            q[self._qpos + 3: self._qpos + 7] = (cy * cp, -sy * sp, cy * sp, sy * cp)
        q[self._susp_qpos] = 0.0
        v = self.data.qvel
        v[self._qvel: self._qvel + 6] = 0.0
        v[self._qvel] = speed_mps * math.cos(yaw_rad)
        v[self._qvel + 1] = speed_mps * math.sin(yaw_rad)
        v[self._susp_dofs] = 0.0
        v[self._spin_dofs] = speed_mps / WHEEL_RADIUS_M
        self._brake_request_nm[:] = self._brake_applied_nm[:] = 0.0
        self._drive_request_nm[:] = self._drive_applied_nm[:] = 0.0
        self._antilock.reset()
        self._traction.reset()
        self.model.dof_frictionloss[self._spin_dofs] = self._rolling_torque_nm
        self.model.pair_friction[self._pairs, :2] = self.road_mu
        self._tyres_at_peak = True
        mujoco.mj_forward(self.model, self.data)

    def position_xy_m(self) -> np.ndarray:
        """Body origin in the world, (2,) [m]."""
        return self.data.qpos[self._qpos: self._qpos + 2].copy()

    def yaw_rad(self) -> float:
        """Heading of the body x axis about world +z [rad]; 0 along the road (+x), positive to the left."""
        w, x, y, z = self.data.qpos[self._qpos + 3: self._qpos + 7]
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    def pitch_rad(self) -> float:
        """Body pitch [rad], positive nose down (the car's dive under braking)."""
        w, x, y, z = self.data.qpos[self._qpos + 3: self._qpos + 7]
        return math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))

    def suspension_travel_m(self) -> np.ndarray:
        """Each wheel's travel from its static position, (4,) [m] (fl, fr, rl, rr; + = compressed)."""
        return self.data.qpos[self._susp_qpos].copy()

    def velocity_world_mps(self) -> np.ndarray:
        """Linear velocity of the body origin in the world, (3,) [m/s]."""
        return self.data.qvel[self._qvel: self._qvel + 3].copy()

    def speed_mps(self) -> float:
        """Forward speed along the car's heading [m/s] (negative when rolling back)."""
        yaw = self.yaw_rad()
        v = self.data.qvel
        return float(v[self._qvel] * math.cos(yaw) + v[self._qvel + 1] * math.sin(yaw))

    def lateral_speed_mps(self) -> float:
        """Sideways speed of the body origin, perpendicular to the heading [m/s], positive to the left."""
        yaw = self.yaw_rad()
        v = self.data.qvel
        return float(-v[self._qvel] * math.sin(yaw) + v[self._qvel + 1] * math.cos(yaw))

    def hub_speeds_mps(self) -> np.ndarray:
        """Each hub's speed along its wheel's heading, (4,) [m/s], from the velocimeter sensors.

        MuJoCo computes sensors at the start of a step, so between steps this is the state
        one physics step earlier, as a wheel-speed sensor's reading would lag.
        """
        return self.data.sensordata[self._hub_speed]

    def wheel_slips(self) -> np.ndarray:
        """Longitudinal slip of each wheel, (4,) (+ braking, - wheelspin; `avsim.vehicle.tyre`)."""
        return slip_ratios(self.hub_speeds_mps(), self.data.qvel[self._spin_dofs] * WHEEL_RADIUS_M)

    def brake_torques_nm(self) -> np.ndarray:
        """The brake torque each wheel received in the last physics step, (4,) [N m]."""
        return self._brake_applied_nm.copy()

    def front_bumper_xy_m(self) -> np.ndarray:
        """Front bumper's centre in the world, (2,) [m]: `FRONT_BUMPER_X_M` ahead of the body origin along the heading."""
        yaw = self.yaw_rad()
        return self.position_xy_m() + FRONT_BUMPER_X_M * np.array([math.cos(yaw), math.sin(yaw)])

    def is_finite(self) -> bool:
        """False once any position or velocity has become NaN or infinite (the physics diverged)."""
        return bool(np.isfinite(self.data.qpos).all() and np.isfinite(self.data.qvel).all())

    # ---- actuation ------------------------------------------------------------------
    def apply(self, controls: Controls) -> None:
        """Set the drive and brake requests and the steering for the coming physics steps."""
        self._drive_request_nm[:] = controls.throttle * self.config.max_drive_torque_nm
        self._brake_request_nm[:] = controls.brake * self._full_brake_nm
        self.data.ctrl[self._steer_act] = controls.steer_rad
        self._apply_drag()

    def _apply_drag(self) -> None:
        """Aerodynamic drag 0.5 rho CdA |v| v on the body, held for the control step."""
        v = self.velocity_world_mps()
        v[2] = 0.0
        k = 0.5 * self.config.air_density_kgpm3 * self.config.drag_area_m2
        self.data.xfrc_applied[self._body, :3] = -k * np.linalg.norm(v) * v

    def advance(self, steps: int) -> None:
        """Run `steps` physics steps: tyre friction, anti-lock brakes, traction control, then
        MuJoCo, each step (see the module docstring).

        Sets `last_max_brake_slip`: the largest slip of any wheel over these steps while the
        brake was requested and that wheel's hub moved faster than SLIP_REPORT_MIN_SPEED_MPS,
        or None if there was no such step.
        """
        model, data = self.model, self.data
        braking = bool(self._brake_request_nm.any())
        driving = bool(self._drive_request_nm.any())
        if not braking and self._brake_applied_nm.any():
            self._brake_applied_nm[:] = 0.0
            self._antilock.reset()
            model.dof_frictionloss[self._spin_dofs] = self._rolling_torque_nm
        if not driving:
            self._drive_applied_nm[:] = 0.0
            self._traction.reset()
            data.ctrl[self._drive_act] = 0.0
        max_slip = -np.inf
        for _ in range(steps):
            hub_mps = data.sensordata[self._hub_speed]
            surface_mps = data.qvel[self._spin_dofs] * WHEEL_RADIUS_M
            slip = slip_ratios(hub_mps, surface_mps)
            self._set_tyre_friction(slip)
            if braking or driving:
                control_slip = slip_ratios(hub_mps, surface_mps, CONTROL_SPEED_FLOOR_MPS)
            if braking:
                self._actuate_brakes(control_slip, hub_mps)
                fast = hub_mps > SLIP_REPORT_MIN_SPEED_MPS
                if fast.any():
                    max_slip = max(max_slip, float(slip[fast].max()))
            if driving:
                self._actuate_drive(control_slip, hub_mps)
            mujoco.mj_step(model, data)
        self.last_max_brake_slip = max_slip if math.isfinite(max_slip) else None

    def _set_tyre_friction(self, slip: np.ndarray) -> None:
        """Each tyre-road pair's friction for its wheel's slip; skipped while every tyre grips
        (below the peak slip the coefficient is the road's own)."""
        gripping = float(np.abs(slip).max()) <= self.config.tyre_peak_slip
        if gripping and self._tyres_at_peak:
            return
        mu = friction_coefficients(self.road_mu, slip, self.config.tyre_peak_slip, self.config.tyre_sliding_ratio)
        self.model.pair_friction[self._pairs, 0] = mu
        self.model.pair_friction[self._pairs, 1] = mu
        self._tyres_at_peak = gripping

    def _actuate_brakes(self, control_slip: np.ndarray, hub_mps: np.ndarray) -> None:
        """The brake torque for the next physics step: the request, limited by the anti-lock
        controller, built up by the hydraulics at a finite rate (released at once)."""
        dt_s = self.model.opt.timestep
        target_nm = self._brake_request_nm
        if self.config.abs_enabled:
            target_nm = self._antilock.limit(target_nm, self._brake_applied_nm, control_slip, hub_mps, dt_s)
        self._brake_applied_nm = np.minimum(target_nm, self._brake_applied_nm + self._brake_rise_nm_per_s * dt_s)
        self.model.dof_frictionloss[self._spin_dofs] = self._rolling_torque_nm + self._brake_applied_nm

    def _actuate_drive(self, control_slip: np.ndarray, hub_mps: np.ndarray) -> None:
        """The drive torque for the next physics step: the request, limited by traction control
        once a driven wheel spins (the controller is only consulted while it has work to do)."""
        spin = -control_slip[_DRIVEN]
        if self.config.traction_control_enabled and (self._traction.active or spin.max() > self.config.abs_target_slip):
            self._drive_applied_nm = self._traction.limit(self._drive_request_nm, self._drive_applied_nm, spin,
                                                          hub_mps[_DRIVEN], self.model.opt.timestep)
        else:
            self._drive_applied_nm = self._drive_request_nm.copy()
        self.data.ctrl[self._drive_act] = self._drive_applied_nm
