"""`map_prior`: brake for the stop the HD map lists, whether or not the camera confirms it.

Production stacks do not wait for a camera to find a stop sign: Apollo takes its stop signs
from the HD map, and Autoware looks up the traffic lights within 200 m in its map. Such a map
prior makes a camera attack pointless, and moves the risk to the map: a sign missing from the
map makes those stacks run it (a known cause of AV stacks running stop signs in CARLA), and a
mapped sign that is gone from the world stops the car for nothing. Assumption: the map is right
about where the stops are. Its failure modes are scenario options (`scenario.map_error`,
`scenario.map_stop_line_offset_m`), and its availability cost is measured, not assumed.
"""

from __future__ import annotations

from avsim.config import PolicyConfig
from avsim.control.estimate import DeadReckonedEstimate
from avsim.control.brake_law import brake_command, required_decel_mps2
from avsim.control.policy_base import GATE_KEYS, POLICIES, BrakeDecision, BrakingPolicy, Observation, PolicyContext
from avsim.world.hd_map import MapHandle


@POLICIES.register("map_prior")
class MapPriorPolicy(BrakingPolicy):
    """The map's stop, refined by the camera (module docstring: source and assumption).

    Two estimates of the distance to the stop line:
    - the map's, through the map handle (the one way this policy reads the map), aiming
      `autopilot_stop_margin_m` short of the mapped line, as the autopilot does;
    - the camera's, exactly `adjusted`'s (front detections through the braking gate, dead-reckoned
      by odometry, never growing), aiming `stop_margin_m` short of it.
    It aims for the nearer of the two: either can be wrong (a map line placed too far, a box read
    too small), and stopping short is the safe error. With no mapped stop ahead (a sign missing
    from the map) only the camera can make it stop; with a mapped stop and no sign, the map
    stops it anyway. As the autopilot, it starts braking once stopping at the aim needs
    `autopilot_decel_fraction` of the car's measured full-brake deceleration, then tracks
    a = v^2 / 2d with the brake calibrated to that measurement.
    """

    uses_map = True
    config_keys = (*GATE_KEYS, "stop_margin_m", "autopilot_stop_margin_m", "autopilot_decel_fraction")
    blind_keys = ("autopilot_stop_margin_m", "autopilot_decel_fraction")  # with no detection the map still stops it

    def __init__(self, config: PolicyConfig, context: PolicyContext, map_handle: MapHandle) -> None:
        super().__init__(config, context)
        self._map = map_handle
        self._camera = DeadReckonedEstimate(context.control_dt_s)
        self._braking = False

    def decide(self, obs: Observation) -> BrakeDecision:
        """Brake by the v^2 / 2d law for the nearer of the map's and the camera's stop lines (each less
        its margin), once that asks for `autopilot_decel_fraction` of full braking; the estimate logged
        is the nearer stop line [m].
        """
        camera_m = self._camera.update(self.gated_stop_sign(obs, "front"), obs.speed_mps)
        map_m = self._map.stop_line_dist_m()
        aims = [line_m - margin_m for line_m, margin_m in ((map_m, self.config.autopilot_stop_margin_m),
                                                             (camera_m, self.config.stop_margin_m)) if line_m is not None]
        if not aims:
            return BrakeDecision(0.0)
        estimate_m = min(m for m in (map_m, camera_m) if m is not None)
        decel = required_decel_mps2(obs.speed_mps, min(aims))
        full_brake_mps2 = self.context.full_brake_decel_mps2
        self._braking = self._braking or decel >= self.config.autopilot_decel_fraction * full_brake_mps2
        if not self._braking:
            return BrakeDecision(0.0, estimate_m, decel)
        return BrakeDecision(brake_command(decel, full_brake_mps2, 1.0), estimate_m, decel)
