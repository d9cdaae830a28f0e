"""Braking policies: what the car does about a stop sign. One registry entry each.

A policy sees an `Observation` each control step and returns a `BrakeDecision`.
Once any policy brakes, the loop disengages the cruise control for the rest of
the run, as a driver lifting off the throttle would.

Distances: `cam_to_bumper_m` is the longitudinal offset from the front camera to
the front bumper; policies assume the stop line lies `stop_line_before_sign_m`
before the sign, the road convention (they cannot see the line itself).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

from avsim.config import PolicyConfig
from avsim.control.pinhole import brake_command, pinhole_distance_m, required_decel_mps2
from avsim.perception.base import Detection
from avsim.registry import Registry

STOP_CLASS = "stop_sign"


@dataclass(frozen=True)
class Observation:
    """What a policy may use at one control step.

    detections: per camera name, highest confidence first.
    stop_line_dist_m: bumper-to-stop-line distance from the map; only `autopilot` reads it.
    """

    time_s: float
    speed_mps: float
    detections: dict[str, list[Detection]]
    stop_line_dist_m: float


@dataclass(frozen=True)
class BrakeDecision:
    """brake in [0, 1]; the estimate and required deceleration are logged when known."""

    brake: float
    est_stop_line_dist_m: float | None = None
    required_decel_mps2: float | None = None


@dataclass(frozen=True)
class PolicyContext:
    """Vehicle and sensor facts a policy is built with."""

    front_f_px: float
    cam_to_bumper_m: float
    control_dt_s: float
    # The car's mean full-brake deceleration at this run's road friction and speed, measured
    # (avsim.vehicle.brake_test) [m/s^2].
    full_brake_decel_mps2: float


class BrakingPolicy(ABC):
    """Base class. `cameras` lists the cameras whose perception the policy needs."""

    cameras: tuple[str, ...] = ("front",)

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        self.config = config
        self.context = context

    def top_stop_sign(self, obs: Observation, camera: str) -> Detection | None:
        """Most confident stop-sign detection above the threshold in `camera`, if any."""
        for det in obs.detections.get(camera, []):
            if det.class_name == STOP_CLASS and det.confidence >= self.config.conf_threshold:
                return det
        return None

    def pinhole_stop_line_dist_m(self, det: Detection) -> float:
        """Bumper-to-stop-line distance estimated from a front-camera box height."""
        sign_depth_m = pinhole_distance_m(self.config.sign_height_m, self.context.front_f_px, det.height_px)
        return sign_depth_m - self.config.stop_line_before_sign_m - self.context.cam_to_bumper_m

    @abstractmethod
    def decide(self, obs: Observation) -> BrakeDecision:
        """Brake command for this control step."""


PolicyFactory = Callable[[PolicyConfig, PolicyContext], BrakingPolicy]
POLICIES: Registry[PolicyFactory] = Registry("policy")


@POLICIES.register("baseline")
class BaselinePolicy(BrakingPolicy):
    """The study's rule: once the front camera sees a stop sign above the confidence
    threshold, apply a constant brake level (`baseline_brake`) until the car stops."""

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._triggered = False

    def decide(self, obs: Observation) -> BrakeDecision:
        det = self.top_stop_sign(obs, "front")
        self._triggered = self._triggered or det is not None
        estimate = self.pinhole_stop_line_dist_m(det) if det else None
        return BrakeDecision(self.config.baseline_brake if self._triggered else 0.0, estimate)


@POLICIES.register("adjusted")
class AdjustedBrakingPolicy(BrakingPolicy):
    """Defence 1: brake by the v^2 / 2d law on the pinhole distance, recomputed every step.

    d_stop = pinhole depth - stop line offset - camera-to-bumper offset - stop margin,
    a = v^2 / (2 d_stop), b = min(a / a_max * M, 1). When the sign leaves the view
    (it does at about 10 m), or is cut by the image border so that its box no
    longer spans the whole sign, the last estimate is carried forward by odometry.
    A box that puts the sign farther away than odometry allows (the car only moves
    towards it) is not believed: the estimate is the smaller of the two. A learned
    detector's boxes of a near, partly hidden sign come out short, and believing
    them releases the brake at the worst moment.
    """

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._estimate_m: float | None = None

    def update_estimate(self, obs: Observation) -> float | None:
        det = self.top_stop_sign(obs, "front")
        dead_reckoned = None if self._estimate_m is None else self._estimate_m - obs.speed_mps * self.context.control_dt_s
        if det is not None and not det.truncated:
            measured = self.pinhole_stop_line_dist_m(det)
            self._estimate_m = measured if dead_reckoned is None else min(measured, dead_reckoned)
        else:
            self._estimate_m = dead_reckoned
        return self._estimate_m

    def decide(self, obs: Observation) -> BrakeDecision:
        estimate = self.update_estimate(obs)
        if estimate is None:
            return BrakeDecision(0.0)
        decel = required_decel_mps2(obs.speed_mps, estimate - self.config.stop_margin_m)
        return BrakeDecision(brake_command(decel, self.config.a_max_mps2, self.config.brake_multiplier), estimate, decel)


@POLICIES.register("side_camera")
class SideCameraPolicy(BaselinePolicy):
    """Defence 2: the baseline rule on the front camera, plus full brake as soon as the
    side camera (yawed towards the roadside) detects a stop sign."""

    cameras = ("front", "side")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._side_triggered = False

    def decide(self, obs: Observation) -> BrakeDecision:
        decision = super().decide(obs)
        self._side_triggered = self._side_triggered or self.top_stop_sign(obs, "side") is not None
        return BrakeDecision(1.0, decision.est_stop_line_dist_m) if self._side_triggered else decision


@POLICIES.register("combined")
class CombinedDefencePolicy(AdjustedBrakingPolicy):
    """Both defences as the study combined them: adjusted braking on the front camera,
    overridden by full brake once the side camera detects a stop sign."""

    cameras = ("front", "side")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._side_triggered = False

    def decide(self, obs: Observation) -> BrakeDecision:
        decision = super().decide(obs)
        self._side_triggered = self._side_triggered or self.top_stop_sign(obs, "side") is not None
        if self._side_triggered:
            return BrakeDecision(1.0, decision.est_stop_line_dist_m, decision.required_decel_mps2)
        return decision


@POLICIES.register("autopilot")
class AutopilotPolicy(BrakingPolicy):
    """Reference row ("CARLA autopilot"): knows the stop line from the map, uses no
    perception. Starts braking when stopping at the line needs `autopilot_decel_fraction` of
    the car's full-brake deceleration, then tracks a = v^2 / 2d with the brake calibrated to
    that deceleration; both are measured at the run's road friction (PolicyContext)."""

    cameras = ()

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._braking = False

    def decide(self, obs: Observation) -> BrakeDecision:
        dist = obs.stop_line_dist_m - self.config.autopilot_stop_margin_m
        decel = required_decel_mps2(obs.speed_mps, dist)
        full_brake_mps2 = self.context.full_brake_decel_mps2
        self._braking = self._braking or decel >= self.config.autopilot_decel_fraction * full_brake_mps2
        if not self._braking:
            return BrakeDecision(0.0, obs.stop_line_dist_m, decel)
        return BrakeDecision(brake_command(decel, full_brake_mps2, 1.0), obs.stop_line_dist_m, decel)
