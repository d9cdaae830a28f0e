"""The car's braking performance, measured: a straight-line stop on a flat test track.

Every figure in avsim that means "the car's full-brake deceleration" comes from here, at
the road friction of the run it describes (the autopilot's brake calibration, the report's
findings, docs/vehicle.md), never from a constant. The test track is a bare road plane with the
car on it, so a measurement takes a fraction of a second; results are cached per process.

    python -m avsim.vehicle.brake_test          # the table docs/vehicle.md quotes

The stop is timed and measured at the physics rate: from the first physics step with the
brake requested to the first at which the car's speed is below STOPPED_SPEED_MPS.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco

from avsim.boundary import run_guarded
from avsim.config import ScenarioConfig, VehicleConfig
from avsim.validation import OneLineArgumentParser, config_flag
from avsim.vehicle.assembly import CAR_PREFIX, add_tyre_contacts, load_car
from avsim.vehicle.physics import Controls, Vehicle
from avsim.vehicle.suspension import GRAVITY_MPS2

STOPPED_SPEED_MPS = 0.1  # as avsim.metrics
# Drag is refreshed at this period, as the closed loop refreshes it every control step [s].
_CONTROL_DT_S = 0.05
_MAX_STOP_TIME_S = 60.0
ROAD_PRESETS = {"dry": 0.9, "wet": 0.5, "snow": 0.2}


@dataclass(frozen=True)
class BrakeTest:
    """One straight-line stop: the entry speed [m/s], road friction, and what was measured."""

    speed_mps: float
    road_friction: float
    brake: float
    stop_time_s: float
    stop_dist_m: float
    max_brake_slip: float  # largest wheel slip while braking above 5 m/s
    peak_pitch_deg: float  # nose down
    max_yaw_deg: float

    @property
    def mean_decel_mps2(self) -> float:
        """Entry speed over stop time [m/s^2]."""
        return self.speed_mps / self.stop_time_s

    @property
    def efficiency(self) -> float:
        """Mean deceleration over mu g: the share of the road's grip the car turns into braking
        (drag and rolling resistance add a little)."""
        return self.mean_decel_mps2 / (self.road_friction * GRAVITY_MPS2)


def make_test_track(vehicle: VehicleConfig, road_friction: float, physics_dt_s: float) -> tuple[mujoco.MjModel, mujoco.MjData, Vehicle]:
    """A flat road plane with the car on it (no scenery, no cameras needed)."""
    spec = mujoco.MjSpec()
    spec.option.timestep = physics_dt_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    road = "make_test_track/road"
    spec.worldbody.add_geom(name=road, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2000, 50, 1])
    spec.worldbody.add_frame().attach_body(load_car(vehicle).body("car"), CAR_PREFIX, "")
    add_tyre_contacts(spec, road, road_friction)
    model = spec.compile()
    data = mujoco.MjData(model)
    return model, data, Vehicle(model, data, vehicle)


@functools.lru_cache(maxsize=64)
def brake_test(vehicle: VehicleConfig, road_friction: float, speed_mps: float = 85 / 3.6, brake: float = 1.0,
               physics_dt_s: float = 0.002) -> BrakeTest:
    """Brake from `speed_mps` to a stop with a constant `brake` command, straight ahead."""
    model, data, car = make_test_track(vehicle, road_friction, physics_dt_s)
    car.place(-1000.0, 0.0, 0.0, speed_mps)
    substeps = max(1, round(_CONTROL_DT_S / physics_dt_s))
    start_x_m = float(car.position_xy_m()[0])
    max_slip, peak_pitch, max_yaw = 0.0, 0.0, 0.0
    steps = 0
    while True:
        car.apply(Controls(brake=brake))
        for _ in range(substeps):
            car.advance(1)
            steps += 1
            max_slip = max(max_slip, car.last_max_brake_slip or 0.0)
            peak_pitch = max(peak_pitch, car.pitch_rad())
            max_yaw = max(max_yaw, abs(car.yaw_rad()))
            if car.speed_mps() < STOPPED_SPEED_MPS:
                return BrakeTest(speed_mps, road_friction, brake, steps * physics_dt_s,
                                 float(car.position_xy_m()[0]) - start_x_m, max_slip, math.degrees(peak_pitch),
                                 math.degrees(max_yaw))
        if steps * physics_dt_s > _MAX_STOP_TIME_S:
            raise RuntimeError(f"the car did not stop within {_MAX_STOP_TIME_S:.0f} s at brake {brake}")


def full_brake_decel_mps2(vehicle: VehicleConfig, road_friction: float, speed_mps: float = 85 / 3.6,
                          physics_dt_s: float = 0.002) -> float:
    """The car's mean full-brake deceleration [m/s^2] from `speed_mps` on this road, measured."""
    return brake_test(vehicle, road_friction, speed_mps, 1.0, physics_dt_s).mean_decel_mps2


def _table(speed_kmh: float) -> str:
    rows = ["| road | mu | ABS | stop time [s] | distance [m] | mean decel [m/s^2] | mu g | efficiency | max slip | peak pitch [deg] |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for name, mu in ROAD_PRESETS.items():
        for abs_on in (True, False):
            test = brake_test(VehicleConfig(abs_enabled=abs_on), mu, speed_kmh / 3.6)
            rows.append(f"| {name} | {mu} | {'on' if abs_on else 'off'} | {test.stop_time_s:.2f} | {test.stop_dist_m:.1f} | "
                        f"{test.mean_decel_mps2:.2f} | {mu * GRAVITY_MPS2:.2f} | {test.efficiency:.3f} | "
                        f"{test.max_brake_slip:.2f} | {test.peak_pitch_deg:.1f} |")
    return "\n".join(rows)


PROG = "python -m avsim.vehicle.brake_test"


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.vehicle.brake_test`: print the car's full-brake stops from `--speed-kmh` on each
    road surface, with and without ABS; returns the exit status.
    """
    parser = OneLineArgumentParser(prog=PROG, description="Full-brake stops of the avsim car on dry, wet and snowy roads.")
    # The closed loop's speed range (scenario.speed_kmh): NaN, 0 or a negative speed is no brake test.
    parser.add_argument("--speed-kmh", type=config_flag(ScenarioConfig, "speed_kmh"), default=85.0)
    args = parser.parse_args(argv)

    def command() -> int:
        print(f"Full brake from {args.speed_kmh:g} km/h, straight, default vehicle config")
        print(_table(args.speed_kmh))
        return 0

    return run_guarded(command, prog=PROG)


if __name__ == "__main__":
    raise SystemExit(main())
