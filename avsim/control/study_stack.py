"""`study_stack`: the decision rules of a public CARLA-ROS node built for the study's experiment,
followed literally, quirks included, so they can be compared with avsim's cleaner policies.

The node's rules (facts from its description, not its code):
- a front detection counts if it is a stop sign at or above the confidence threshold (0.5 in
  the node) and its box centre lies in the right half of the front image;
- it brakes only when the front pinhole estimate d = H f / h is below 40 m, computed with an
  assumed sign height H of 1.0 m: a = v^2 / (2 d), b = min(a / 9.81 * 0.6, 0.8);
- once braking has started and the side camera sees a stop sign, it brakes with
  b = min(a / 9.81 * 0.8, 1), a from the last front estimate;
- once braking has started and neither camera sees the sign in a frame, it sends zero throttle
  and zero brake: it coasts.
"""

from __future__ import annotations

from avsim.config import PolicyConfig
from avsim.control.brake_law import required_decel_mps2
from avsim.control.policy_base import POLICIES, BrakeDecision, BrakingPolicy, Observation, PolicyContext
from avsim.perception.base import Detection
from avsim.sensors.pinhole import pinhole_distance_m

# The node's constants.
A_MAX_MPS2 = 9.81
FRONT_GAIN, FRONT_CAP = 0.6, 0.8
SIDE_GAIN, SIDE_CAP = 0.8, 1.0


@POLICIES.register("study_stack")
class StudyStackPolicy(BrakingPolicy):
    """The study stack's rules, literally (module docstring). How it differs from avsim's policies:

    - its distance is the camera's pinhole depth to the sign, d = H f / h, with no stop-line or
      camera-to-bumper offset, and with H = `policy.study_sign_height_m` (1.0 m, the node's
      assumption) where avsim's signs are 0.762 m: d reads 31 % long, so it triggers late (at a
      true 30.5 m for its 40 m) and asks for less deceleration than it needs;
    - the gate compares that raw d with `policy.trigger_dist_m` (40 m, the node's);
    - the front brake is capped at 0.8 with a gain of 0.6, where `adjusted` uses
      b = min(a / a_max * M, 1);
    - a front detection counts only in the right half of the image;
    - the side camera only raises the brake after the front camera started braking, and then
      from the last front estimate;
    - it does not latch: in a frame where neither camera sees the sign it coasts (brake 0),
      where `baseline` keeps its brake and `adjusted` dead-reckons its estimate.
    The confidence threshold is `policy.conf_threshold` (0.5 by default, as in the node).
    """

    cameras = ("front", "side")
    config_keys = ("conf_threshold", "trigger_dist_m", "study_sign_height_m")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._braking = False
        self._last_front_d_m: float | None = None

    def _counts(self, det: Detection) -> bool:
        """A front stop sign counts only with its box centre in the right half of the image."""
        centre_u_px = (det.box_xyxy_px[0] + det.box_xyxy_px[2]) / 2
        return centre_u_px > self.context.cameras["front"].cx_px

    def _pinhole_d_m(self, det: Detection) -> float:
        return pinhole_distance_m(self.config.study_sign_height_m, self.context.cameras[det.camera].f_px, det.height_px)

    def decide(self, obs: Observation) -> BrakeDecision:
        """The node's brake for this frame. Its d is not a stop-line distance, so the decision
        logs no stop-line estimate."""
        front = next((d for d in self.stop_signs(obs, "front") if self._counts(d)), None)
        front_d_m = self._pinhole_d_m(front) if front is not None else None
        trigger_m = self.config.trigger_dist_m
        front_in_range = front_d_m is not None and (trigger_m is None or front_d_m < trigger_m)
        if front_in_range:
            self._braking = True
            self._last_front_d_m = front_d_m
        if self._braking and self.stop_signs(obs, "side"):
            decel = required_decel_mps2(obs.speed_mps, self._last_front_d_m)
            return BrakeDecision(min(decel / A_MAX_MPS2 * SIDE_GAIN, SIDE_CAP), None, decel)
        if front_in_range:
            decel = required_decel_mps2(obs.speed_mps, front_d_m)
            return BrakeDecision(min(decel / A_MAX_MPS2 * FRONT_GAIN, FRONT_CAP), None, decel)
        return BrakeDecision(0.0)  # not yet braking, or coasting: neither camera sees the sign
