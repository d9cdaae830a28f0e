"""Scenarios that cannot mean what they say, refused before they run.

Each field of a config is checked alone by its dataclass (`avsim.config`, `avsim.validation`);
some combinations are valid field by field and still meaningless, and would be reported as
results no physics produced:

- a car that starts at rest inside the braking gate of a perceiving policy: it sees the sign
  before it moves and never drives, and the run reads "stopped before the line" with a
  time to stop of one control step, a stop that did not happen;
- a perceiving policy with no perception (`perception.kind = none`): it drives blind, and
  every run past the sign would be the missing perception's, not the policy's.

`check_meaningful` is called when an experiment or sweep file is loaded
(`avsim.experiments.spec.check_registry_names`) and before every run (`avsim.runner`).
"""

from __future__ import annotations

from avsim.config import SimConfig
from avsim.control.policies import POLICIES
from avsim.errors import ConfigError
from avsim.perception.factory import PERCEPTIONS


def check_meaningful(config: SimConfig) -> None:
    """A one-line ConfigError when `config` is a scenario that cannot mean what it says."""
    policy_class = POLICIES.get(config.policy.name)
    perceives = bool(policy_class.cameras)
    if perceives and config.perception.kind == "none":
        seeing = ", ".join(name for name in PERCEPTIONS.names() if name != "none")
        raise ConfigError(f"policy '{config.policy.name}' brakes on what a perception sees, and perception.kind is "
                          f"none, so it would drive blind; choose a perception ({seeing}) or a map-reading policy (autopilot)")
    scenario, gate_m = config.scenario, config.policy.trigger_dist_m
    nearest_start_m = scenario.start_dist_m - scenario.start_jitter_m
    if perceives and gate_m is not None and scenario.start_speed_kmh == 0 and nearest_start_m <= gate_m:
        raise ConfigError(f"scenario.start_dist_m = {scenario.start_dist_m:g} m (less {scenario.start_jitter_m:g} m of "
                          f"jitter) starts the car at rest inside the braking gate (policy.trigger_dist_m = "
                          f"{gate_m:g} m): it would stop before it drives, a stop no physics made; start more than "
                          f"{gate_m + scenario.start_jitter_m:g} m out, or give it a start speed "
                          "(scenario.start_speed_kmh)")
