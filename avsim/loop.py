"""The closed loop: one fixed-dt control cycle, in one order, written down once.

Each control step (every `loop.control_dt_s`, 20 Hz by default):

    render -> perceive -> decide -> actuate -> N physics steps -> record

where N = control_dt_s / physics_dt_s (25 at the defaults). Rendering happens inside
perception, only for the cameras the policy uses and only in the modality the
perception needs. Commands are held constant over the N physics steps (zero-order
hold), as a real ECU's would be between sensor frames.

`step` is `perceive` (render -> perceive), the policy's decision, then `actuate` (actuate ->
physics -> record). A controller outside the loop, such as the Gymnasium environment
(`avsim.gym`), calls the two halves itself with its own decision in between.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import mujoco
import numpy as np

from avsim.config import SimConfig
from avsim.control.cruise import LaneKeeper, SpeedController
from avsim.control.policies import POLICIES, STOP_CLASS, BrakeDecision, CameraModel, Observation, PolicyContext
from avsim.errors import PhysicsError
from avsim.metrics import STOPPED_SPEED_MPS, RunResult, StepRecord, summarise
from avsim.perception.base import Detection
from avsim.perception.factory import FrameDetectorCache, build_perception
from avsim.sensors.camera import CAMERA_NAMES, CameraRig
from avsim.vehicle.brake_test import full_brake_decel_mps2
from avsim.vehicle.physics import FRONT_BUMPER_X_M, Controls, Vehicle
from avsim.world.hd_map import HdMap, MapHandle
from avsim.world.scene import build_scene

# A car past the sign by this much has certainly run it [m].
RAN_PAST_SIGN_M = 40.0
MAX_PLAUSIBLE_SPEED_MPS = 100.0
_INSTABILITY_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                         mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADCTRL)


class ClosedLoop:
    """A single run of one `SimConfig`. Build, then `run()` (or `step()` repeatedly)."""

    def __init__(self, config: SimConfig, detectors: FrameDetectorCache | None = None) -> None:
        """detectors: where a pixel perception takes its network from, shared with other runs (the
        lock-step batch); None builds this run's own."""
        self.config = config
        policy_factory = POLICIES.get(config.policy.name)  # fail on a bad name before building anything
        self.model, self.scene = build_scene(config)
        self.data = mujoco.MjData(self.model)
        self.vehicle = Vehicle(self.model, self.data, config.vehicle)
        self.rig = CameraRig(self.model, config.camera, fog=config.scenario.fog_end_m > 0)
        self.perception = build_perception(config.perception, config.camera, self.model, self.scene, config.scenario.seed, detectors)
        context = PolicyContext(
            cameras={name: self._camera_model(name) for name in CAMERA_NAMES},
            control_dt_s=config.loop.control_dt_s,
            # Measured on a test track at this run's road friction and speed, not assumed.
            full_brake_decel_mps2=full_brake_decel_mps2(config.vehicle, config.scenario.road_friction,
                                                        config.scenario.speed_kmh / 3.6, config.loop.physics_dt_s),
        )
        # The map is privileged: only a policy that declares it uses the map is handed it.
        self.hd_map = HdMap.for_scene(self.scene.stop_line_x_m, config.scenario)
        map_handle = MapHandle(self.hd_map, lambda: float(self.vehicle.front_bumper_xy_m()[0]))
        extra = {"map_handle": map_handle} if getattr(policy_factory, "uses_map", False) else {}
        self.policy = policy_factory(config.policy, context, **extra)
        self.cruise = SpeedController(config.scenario.speed_kmh / 3.6)
        self.lane = LaneKeeper(self.scene.layout.lane_center_y_m)
        self.records: list[StepRecord] = []
        self.time_s = 0.0
        self.braking = False
        self.stopped = False
        self._place_car(np.random.default_rng(config.scenario.seed))

    def _camera_model(self, name: str) -> CameraModel:
        """A camera as the policies know it: intrinsics, yaw and how far the bumper is ahead of it."""
        intrinsics = self.rig.intrinsics(name)
        cam_x_m = float(self.model.cam_pos[self.model.camera(f"car/{name}").id][0])
        yaw_deg = self.config.camera.side_yaw_deg if name == "side" else 0.0
        return CameraModel(intrinsics.f_px, intrinsics.principal_point_px[0], math.radians(yaw_deg), FRONT_BUMPER_X_M - cam_x_m)

    def _place_car(self, rng: np.random.Generator) -> None:
        scenario = self.config.scenario
        jitter_m = float(rng.uniform(-scenario.start_jitter_m, scenario.start_jitter_m))
        bumper_x = self.scene.stop_line_x_m - scenario.start_dist_m + jitter_m
        self.vehicle.place(bumper_x - FRONT_BUMPER_X_M, self.scene.layout.lane_center_y_m, 0.0, scenario.start_speed_kmh / 3.6)

    # ---- one control step ------------------------------------------------------------
    def step(self) -> StepRecord:
        """Advance one control step; returns (and stores) its record.

        The record holds the state at sensing time (the start of the step) with the
        detections and commands that state produced.
        """
        # render -> perceive, then the rest
        return self.step_with(self.perceive(self.policy.cameras))

    def step_with(self, detections: dict[str, list[Detection]]) -> StepRecord:
        """The rest of a control step once the policy's cameras have been perceived at the current
        state: decide -> actuate -> N physics steps -> record. `step` calls it with `perceive`'s
        detections; the lock-step batch with the detections of its shared network call."""
        speed = self.vehicle.speed_mps()
        obs = Observation(self.time_s, speed, detections)
        decision = self.policy.decide(obs)
        return self.actuate(self._controls(decision, speed), decision, detections)

    def perceive(self, cameras: tuple[str, ...]) -> dict[str, list[Detection]]:
        """render -> perceive at the current state: each of `cameras`' detections, highest confidence first."""
        return self.perception.detect_cameras(self.rig, self.data, cameras)

    def actuate(self, controls: Controls, decision: BrakeDecision, detections: dict[str, list[Detection]]) -> StepRecord:
        """The rest of a control step once its commands are known: actuate -> N physics steps -> record.

        `step` calls it with the policy's commands. A controller outside the loop (the Gymnasium
        environment, `avsim.gym`) calls `perceive`, decides, then calls this with its own
        commands; `decision` and `detections` are only recorded. Returns (and stores) the record.
        """
        self.vehicle.apply(controls)
        record = self._record(controls, decision, detections)  # state at sensing time
        # N physics steps (tyres, anti-lock brakes and traction control act at each)
        self.vehicle.advance(self.config.loop.substeps)
        self.time_s = round(self.time_s + self.config.loop.control_dt_s, 9)
        self._check_physics()
        # record: the step's largest braking slip is known only once its physics has run
        record = dataclasses.replace(record, max_brake_slip=self.vehicle.last_max_brake_slip)
        self.records.append(record)
        return record

    def lane_steer_rad(self, speed_mps: float) -> float:
        """The lane keeper's steering command at the current state [rad], left +."""
        xy = self.vehicle.position_xy_m()
        return self.lane.steer_rad(float(xy[1]), self.vehicle.yaw_rad(), speed_mps)

    def _controls(self, decision: BrakeDecision, speed_mps: float) -> Controls:
        self.braking = self.braking or decision.brake > 0
        throttle = 0.0 if self.braking else self.cruise.throttle(speed_mps, self.config.loop.control_dt_s)
        return Controls(throttle=throttle, brake=decision.brake, steer_rad=self.lane_steer_rad(speed_mps))

    def _check_physics(self) -> None:
        # MuJoCo resets the state by itself when it meets NaN or huge values, so a finite
        # state is not proof of health: its instability warnings are.
        unstable = any(self.data.warning[w].number > 0 for w in _INSTABILITY_WARNINGS)
        if not self.vehicle.is_finite() or unstable:
            raise PhysicsError(f"physics diverged at t = {self.time_s:.2f} s (NaN or bad acceleration); lower loop.physics_dt_s")
        if abs(self.vehicle.speed_mps()) > MAX_PLAUSIBLE_SPEED_MPS:
            raise PhysicsError(f"physics diverged at t = {self.time_s:.2f} s (speed {self.vehicle.speed_mps():.0f} m/s); lower loop.physics_dt_s")

    def _record(self, controls: Controls, decision: BrakeDecision, detections: dict[str, list[Detection]]) -> StepRecord:
        xy = self.vehicle.position_xy_m()
        bumper_x = float(self.vehicle.front_bumper_xy_m()[0])
        flat = tuple(d for dets in detections.values() for d in dets)
        stop_confs = [d.confidence for d in flat if d.class_name == STOP_CLASS and d.confidence >= self.config.policy.conf_threshold]
        return StepRecord(
            time_s=self.time_s, x_m=float(xy[0]), y_m=float(xy[1]), yaw_rad=self.vehicle.yaw_rad(),
            speed_mps=self.vehicle.speed_mps(), throttle=controls.throttle, brake=controls.brake, steer_rad=controls.steer_rad,
            pitch_rad=self.vehicle.pitch_rad(),
            stop_line_dist_m=self.scene.stop_line_x_m - bumper_x,
            sign_dist_m=self.scene.stop_sign.base_pos_m[0] - bumper_x,
            est_stop_line_dist_m=decision.est_stop_line_dist_m,
            required_decel_mps2=decision.required_decel_mps2 if decision.required_decel_mps2 is None or math.isfinite(decision.required_decel_mps2) else None,
            top_stop_conf=max(stop_confs, default=0.0),
            detections=flat,
        )

    # ---- whole run ---------------------------------------------------------------------
    def done(self) -> bool:
        """Whether the run is over: stopped after braking, ran well past the sign (braking or
        not: a car that coasts on after a brief brake has run it too), or timed out."""
        self.stopped = self.braking and self.vehicle.speed_mps() < STOPPED_SPEED_MPS
        sign_dist_m = self.scene.stop_sign.base_pos_m[0] - float(self.vehicle.front_bumper_xy_m()[0])
        ran_past = sign_dist_m < -RAN_PAST_SIGN_M
        return self.stopped or ran_past or self.time_s >= self.config.loop.max_time_s

    def run(self, on_step: Callable[[ClosedLoop, StepRecord], None] | None = None) -> RunResult:
        """Step until the car stops, runs well past the sign, or time runs out."""
        while not self.done():
            record = self.step()
            if on_step is not None:
                on_step(self, record)
        return self.result(self.stopped)

    def result(self, stopped: bool) -> RunResult:
        """The result record of the steps so far, the run having ended at the current state;
        stopped: whether it ended because the car stopped (`done` sets `self.stopped`)."""
        final = self._record(Controls(brake=self.records[-1].brake), BrakeDecision(self.records[-1].brake), {})
        sign = self.scene.stop_sign.base_pos_m
        return summarise(self.records, final, (sign[0], sign[1]), stopped, self.config.to_dict(),
                         stop_required=self.scene.stop_required)

    def close(self) -> None:
        """Release the perception's and the camera rig's resources (worker threads, GL contexts)."""
        self.perception.close()
        self.rig.close()
