"""Test helpers importable from any test module (`from helpers import make_config`).

They live outside conftest.py because a second conftest (tests/perception/detector/)
would shadow a `from helpers import ...`.
"""

from __future__ import annotations

from avsim.config import SimConfig, with_overrides
from avsim.experiments.run_task import RunSpec

# Short oracle runs: the sign is in range within a second, the car stops in a few.
SHORT_RUN = {"speed_kmh": 40.0, "start_speed_kmh": 40.0, "start_dist_m": 50.0}


def make_config(**sections) -> SimConfig:
    """SimConfig with per-section overrides, e.g. make_config(scenario={"town": "town03"}).

    Tests use the `oracle` perception unless they name another: physics and policy tests
    must not depend on how well the learned detector happens to be trained.
    """
    sections = {**sections, "perception": {"kind": "oracle", **sections.get("perception", {})}}
    return with_overrides(SimConfig(), sections)


def short_run_spec(cell: str, seed: int = 0, **sections) -> RunSpec:
    """A batch spec of a short oracle run (`SHORT_RUN`) at `seed`, with the given config sections."""
    sections.setdefault("scenario", {})
    sections["scenario"] = {**SHORT_RUN, "seed": seed, **sections["scenario"]}
    return RunSpec("short", cell, seed, make_config(**sections))
