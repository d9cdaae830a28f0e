"""What every braking policy shares: its observation, its decision, what it knows of the car's
cameras, the braking gate, and the registry the policies are looked up in.

A policy sees an `Observation` each control step and returns a `BrakeDecision`. Once any
policy brakes, the loop disengages the cruise control for the rest of the run, as a driver
lifting off the throttle would.

An observation holds only what the car perceives: time, its own speed (odometry) and the
detections of its cameras. Where the stop line is on the map is privileged: only a policy that
declares `uses_map` is built with a map handle (`avsim.world.hd_map.MapHandle`), and perceiving
policies are not (dm_control keeps a task's privileged state out of observations the same way).

Distances: each camera's pinhole estimate is turned into a distance from the front bumper to
the stop line using the camera's mounting (`CameraModel`) and the road convention that the stop
line lies `stop_line_before_sign_m` before the sign (a policy cannot see the line itself).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from avsim.config import PolicyConfig
from avsim.sensors.pinhole import pinhole_distance_m
from avsim.perception.base import Detection
from avsim.registry import Registry

STOP_CLASS = "stop_sign"
# The policy keys of the braking gate (`BrakingPolicy.gated_stop_sign`): a policy that acts through
# it reads these four.
GATE_KEYS = ("conf_threshold", "trigger_dist_m", "sign_height_m", "stop_line_before_sign_m")


@dataclass(frozen=True)
class Observation:
    """What a policy may use at one control step.

    detections: per camera name, highest confidence first.
    """

    time_s: float
    speed_mps: float
    detections: dict[str, list[Detection]]


@dataclass(frozen=True)
class BrakeDecision:
    """brake in [0, 1]; the estimate and required deceleration are logged when known."""

    brake: float
    est_stop_line_dist_m: float | None = None
    required_decel_mps2: float | None = None


@dataclass(frozen=True)
class CameraModel:
    """A car camera as a policy knows it: pinhole intrinsics and where it is mounted.

    f_px: focal length [px]; cx_px: principal point's x [px]; yaw_right_rad: the optical axis
    turned right of the car's heading [rad]; bumper_ahead_m: how far the front bumper is ahead
    of the camera along the car's x [m].
    """

    f_px: float
    cx_px: float
    yaw_right_rad: float
    bumper_ahead_m: float

    def sign_ahead_m(self, det: Detection, sign_height_m: float) -> float:
        """How far ahead of the camera, along the car's heading, a sign of `sign_height_m` is [m].

        Its depth along the optical axis is Z = H f / h (the box's height: a vertical edge's
        image height depends only on its depth); the box centre's column gives its offset X to
        the right of the axis, X = (u - cx) Z / f. Turning (Z, X) by the camera's yaw into the
        car's frame, the distance ahead is Z cos(yaw) - X sin(yaw).
        """
        depth_m = pinhole_distance_m(sign_height_m, self.f_px, det.height_px)
        centre_u_px = (det.box_xyxy_px[0] + det.box_xyxy_px[2]) / 2
        right_m = (centre_u_px - self.cx_px) * depth_m / self.f_px
        return depth_m * math.cos(self.yaw_right_rad) - right_m * math.sin(self.yaw_right_rad)


@dataclass(frozen=True)
class PolicyContext:
    """Vehicle and sensor facts a policy is built with.

    cameras: "front" and "side" as the policy knows them.
    full_brake_decel_mps2: the car's mean full-brake deceleration at this run's road friction and
    speed, measured (avsim.vehicle.brake_test) [m/s^2].
    """

    cameras: Mapping[str, CameraModel]
    control_dt_s: float
    full_brake_decel_mps2: float


class BrakingPolicy(ABC):
    """Base class. `cameras` lists the cameras whose perception the policy needs; `uses_map`
    says whether it is built with the map handle (only reference policies are); `config_keys`
    lists the `policy.*` keys it reads besides `name`: a key it does not list is refused when a
    user sets it for this policy (`avsim.config_owners`), and a test checks the list against the
    keys a policy really reads. `blind_keys` are those of `config_keys` that still change its
    decisions when it is given no detection (perception.kind = none, or no camera): a key that acts
    only on a detection (the braking gate's, the brake it applies once triggered) is refused there."""

    cameras: tuple[str, ...] = ("front",)
    uses_map: bool = False
    config_keys: tuple[str, ...] = ()
    blind_keys: tuple[str, ...] = ()

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        self.config = config
        self.context = context

    def stop_signs(self, obs: Observation, camera: str) -> list[Detection]:
        """The camera's stop-sign detections at or above the confidence threshold, most confident first."""
        return [d for d in obs.detections.get(camera, [])
                if d.class_name == STOP_CLASS and d.confidence >= self.config.conf_threshold]

    def stop_line_estimate_m(self, det: Detection) -> float:
        """Bumper-to-stop-line distance estimated from a detection's box with its camera's pinhole model."""
        camera = self.context.cameras[det.camera]
        ahead_m = camera.sign_ahead_m(det, self.config.sign_height_m)
        return ahead_m - self.config.stop_line_before_sign_m - camera.bumper_ahead_m

    def gated_stop_sign(self, obs: Observation, camera: str) -> tuple[Detection, float] | None:
        """The braking gate: the most confident stop sign above the threshold whose estimated
        distance to the stop line is within `trigger_dist_m` (any, with no gate), and that
        estimate; None if there is none. A policy acts on no other detection."""
        trigger_m = self.config.trigger_dist_m
        for det in self.stop_signs(obs, camera):
            estimate_m = self.stop_line_estimate_m(det)
            if trigger_m is None or estimate_m <= trigger_m:
                return det, estimate_m
        return None

    @abstractmethod
    def decide(self, obs: Observation) -> BrakeDecision:
        """Brake command for this control step."""


PolicyFactory = Callable[..., BrakingPolicy]
POLICIES: Registry[PolicyFactory] = Registry("policy")
