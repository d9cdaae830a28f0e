"""The `autopilot` reference policy: it knows where the stop line is from the map.

It stands for the study's "CARLA autopilot" row: a planner that takes stop lines from its HD
map and uses no perception. It is the one policy built with the map handle.
"""

from __future__ import annotations

from avsim.config import PolicyConfig
from avsim.control.brake_law import brake_command, required_decel_mps2
from avsim.control.policy_base import POLICIES, BrakeDecision, BrakingPolicy, Observation, PolicyContext
from avsim.world.hd_map import MapHandle


@POLICIES.register("autopilot")
class AutopilotPolicy(BrakingPolicy):
    """Reference row ("CARLA autopilot"): reads the distance to the next stop line from the map
    handle, uses no camera. Starts braking when stopping at the line needs
    `autopilot_decel_fraction` of the car's full-brake deceleration, then tracks a = v^2 / 2d
    with the brake calibrated to that deceleration; both are measured at the run's road
    friction (PolicyContext). With no stop line ahead on the map it does not brake."""

    cameras = ()
    uses_map = True
    config_keys = ("autopilot_stop_margin_m", "autopilot_decel_fraction")
    blind_keys = config_keys  # it never gets a detection

    def __init__(self, config: PolicyConfig, context: PolicyContext, map_handle: MapHandle) -> None:
        super().__init__(config, context)
        self._map = map_handle
        self._braking = False

    def decide(self, obs: Observation) -> BrakeDecision:
        """Brake by the v^2 / 2d law for the map's stop line less `autopilot_stop_margin_m`, from the step
        that asks for `autopilot_decel_fraction` of full braking on; nothing before the map shows a line.
        """
        line_m = self._map.stop_line_dist_m()
        if line_m is None:
            return BrakeDecision(0.0)
        decel = required_decel_mps2(obs.speed_mps, line_m - self.config.autopilot_stop_margin_m)
        full_brake_mps2 = self.context.full_brake_decel_mps2
        self._braking = self._braking or decel >= self.config.autopilot_decel_fraction * full_brake_mps2
        if not self._braking:
            return BrakeDecision(0.0, line_m, decel)
        return BrakeDecision(brake_command(decel, full_brake_mps2, 1.0), line_m, decel)
