"""The car's HD map and the handle through which a map-reading policy sees it.

Production stacks take stop lines from their HD map (Apollo its stop signs, Autoware its
traffic lights). In avsim the map is built from the scene, with the scenario's map errors
applied (`HdMap.for_scene`): `scenario.map_stop_line_offset_m` moves the mapped stop line along
the road (a map that disagrees with the world); `scenario.map_error` leaves the junction's stop
off the map ("missing_stop", a known cause of stacks running stop signs in CARLA) or lists one
the world does not have ("phantom_stop"). The map is privileged: only a policy that declares
`uses_map` is given a `MapHandle`, and nothing else in a policy's observation comes from it.

World frame as in `avsim.world.road` (x along the road, y left, z up) [m].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from avsim.config import ScenarioConfig

# A stop line the bumper has just crossed still counts, so a car that overshoots a little keeps
# braking for it instead of looking for the next one [m].
_BEHIND_TOLERANCE_M = 30.0


@dataclass(frozen=True)
class HdMap:
    """Stop lines on the car's road, as world x of their near edge [m], in driving order."""

    stop_lines_x_m: tuple[float, ...]

    @classmethod
    def for_scene(cls, stop_line_x_m: float, scenario: ScenarioConfig) -> HdMap:
        """The map of a scene whose junction's stop line is (or would be) at world x `stop_line_x_m`:
        the junction's stop when the world requires one, with the scenario's map errors applied."""
        mapped = (scenario.stop_required and scenario.map_error != "missing_stop") or scenario.map_error == "phantom_stop"
        return cls((stop_line_x_m + scenario.map_stop_line_offset_m,) if mapped else ())

    def next_stop_line_x_m(self, x_m: float) -> float | None:
        """The first mapped stop line at or ahead of world x `x_m`; None if there is none."""
        return next((line for line in sorted(self.stop_lines_x_m) if line >= x_m - _BEHIND_TOLERANCE_M), None)



class MapHandle:
    """The map plus the car's localisation: where the next mapped stop line is from the bumper.

    bumper_x_m: reads the front bumper's world x now (the car's own localisation).
    """

    def __init__(self, hd_map: HdMap, bumper_x_m: Callable[[], float]) -> None:
        self._map = hd_map
        self._bumper_x_m = bumper_x_m

    def stop_line_dist_m(self) -> float | None:
        """Bumper to the next mapped stop line along the road [m] (negative once past it); None
        if the map has no stop line ahead."""
        bumper_m = self._bumper_x_m()
        line_m = self._map.next_stop_line_x_m(bumper_m)
        return None if line_m is None else line_m - bumper_m
