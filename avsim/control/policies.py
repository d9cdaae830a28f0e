"""The braking policies, one registry entry each: the study's rule, its two defences and their
combination here; the map-reading autopilot (`avsim.control.autopilot`), the study's literal
stack (`avsim.control.study_stack`), and the defences beyond the study, temporal voting
(`avsim.control.temporal_vote`) and the map prior (`avsim.control.map_prior`), in their own
modules. Importing this module registers them all in `POLICIES`.

Every perceiving policy here acts on a detection only through the braking gate
(`BrakingPolicy.gated_stop_sign`): a stop sign above `policy.conf_threshold` whose pinhole
estimate of the distance to the stop line is at most `policy.trigger_dist_m`.
"""

from __future__ import annotations

from avsim.config import PolicyConfig
from avsim.control import autopilot, map_prior, study_stack, temporal_vote  # noqa: F401  (their registry entries)
from avsim.control.estimate import DeadReckonedEstimate
from avsim.control.brake_law import brake_command, required_decel_mps2
from avsim.control.policy_base import (GATE_KEYS, POLICIES, STOP_CLASS, BrakeDecision, BrakingPolicy, CameraModel,
                                       Observation, PolicyContext)

__all__ = ["POLICIES", "STOP_CLASS", "BrakeDecision", "BrakingPolicy", "CameraModel", "Observation", "PolicyContext"]


@POLICIES.register("baseline")
class BaselinePolicy(BrakingPolicy):
    """The study's rule: once the front camera sees a stop sign through the braking gate, apply a
    constant brake level (`baseline_brake`) until the car stops."""

    config_keys = (*GATE_KEYS, "baseline_brake")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._triggered = False

    def decide(self, obs: Observation) -> BrakeDecision:
        """`baseline_brake` from the first step the front camera sees a stop sign through the braking gate
        on, else 0; the estimate is this step's gated one (None without a gated sign).
        """
        gated = self.gated_stop_sign(obs, "front")
        self._triggered = self._triggered or gated is not None
        return BrakeDecision(self.config.baseline_brake if self._triggered else 0.0, gated[1] if gated else None)


@POLICIES.register("adjusted")
class AdjustedBrakingPolicy(BrakingPolicy):
    """Defence 1: brake by the v^2 / 2d law on the pinhole distance, recomputed every step.

    d_stop = pinhole distance to the stop line - stop margin, a = v^2 / (2 d_stop),
    b = min(a / a_max * M, 1). Its rules:
    - it acts on a front detection only through the braking gate (`trigger_dist_m`);
    - when the sign leaves the view (it does at about 10 m), or is cut by the image border so
      that its box no longer spans the whole sign, the last estimate is carried forward by
      odometry (speed times the control period);
    - the estimate never grows: a box that puts the sign farther away than odometry allows
      (the car only moves towards it) is not believed, and the estimate is the smaller of the
      two. A learned detector's boxes of a near, partly hidden sign come out short, and
      believing them would release the brake at the worst moment.
    (`avsim.control.estimate.DeadReckonedEstimate` keeps it.)
    """

    config_keys = (*GATE_KEYS, "stop_margin_m", "a_max_mps2", "brake_multiplier")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._estimate = DeadReckonedEstimate(context.control_dt_s)

    def update_estimate(self, obs: Observation) -> float | None:
        """This step's front-camera estimate of the distance to the stop line (`DeadReckonedEstimate`)."""
        return self._estimate.update(self.gated_stop_sign(obs, "front"), obs.speed_mps)

    def decide(self, obs: Observation) -> BrakeDecision:
        """The v^2 / 2d brake for this step's stop-line estimate less `stop_margin_m` (0 without an estimate)."""
        estimate = self.update_estimate(obs)
        if estimate is None:
            return BrakeDecision(0.0)
        decel = required_decel_mps2(obs.speed_mps, estimate - self.config.stop_margin_m)
        return BrakeDecision(brake_command(decel, self.config.a_max_mps2, self.config.brake_multiplier), estimate, decel)


class SideCameraTrigger(BrakingPolicy):
    """Defence 2's trigger, shared by `side_camera` and `combined`: whatever the front-camera rule
    it is mixed into decides, full brake from the first step the side camera (yawed towards the
    roadside) sees a stop sign through the braking gate (its own pinhole estimate, with the side
    camera's intrinsics and yaw) to the end of the run. The front rule's estimate is kept."""

    cameras = ("front", "side")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._side_triggered = False

    def decide(self, obs: Observation) -> BrakeDecision:
        """The front rule's decision, or full brake (its estimate kept) once the side camera has triggered."""
        decision = super().decide(obs)
        self._side_triggered = self._side_triggered or self.gated_stop_sign(obs, "side") is not None
        if self._side_triggered:
            return BrakeDecision(1.0, decision.est_stop_line_dist_m, decision.required_decel_mps2)
        return decision


@POLICIES.register("side_camera")
class SideCameraPolicy(SideCameraTrigger, BaselinePolicy):
    """Defence 2: the baseline rule on the front camera, plus full brake as soon as the side
    camera sees a stop sign through the braking gate (`SideCameraTrigger`)."""


@POLICIES.register("combined")
class CombinedDefencePolicy(SideCameraTrigger, AdjustedBrakingPolicy):
    """Both defences as the study combined them: adjusted braking on the front camera,
    overridden by full brake once the side camera sees a stop sign through the braking gate
    (`SideCameraTrigger`)."""
