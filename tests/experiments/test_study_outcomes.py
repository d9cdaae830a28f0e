"""The study's claims as physics assertions, on the shipped experiment files at 85 km/h.

Each test runs one cell of `experiments/*.toml` exactly as `avsim reproduce` (and
`avsim run --config FILE --cell NAME --seed 0`) runs it: detector perception on the rendered
frames, seed 0's start jitter, lighting and sensor noise. One seed is an example, not a rate:
`avsim reproduce` runs five seeds per cell and reports each cell's stop rate with its Wilson
interval. What these tests pin is seed 0's outcome, and, for every outcome, its physics: where
the policy began braking set against the car's own measured stopping distance
(`avsim.vehicle.brake_test`) at the hardest brake the policy commanded.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from avsim.config import VehicleConfig
from avsim.experiments import load_experiment
from avsim.runner import run_config
from avsim.metrics import RunResult
from avsim.vehicle.brake_test import brake_test

EXPERIMENTS_DIR = Path(__file__).resolve().parents[2] / "experiments"
SEED = 0
DEFENDED_CELLS = ("Town07 standard", "Town03 far", "Town03 near", "Town10 far", "Town10 near")
# One control step at 85 km/h is 1.2 m (0.05 s); the brake test starts its stop at the same
# command, so its distance and the loop's agree to well within a step.
PHYSICS_TOLERANCE_M = 0.6

pytestmark = pytest.mark.slow

# Seed 0's outcome per cell, as measured: True = stopped before the sign. With the study's 40 m
# braking gate the margin is thin (a full stop from 85 km/h takes 34 m), so a yang-attacked sign
# that is confirmed a few metres late inside the gate is enough to run past it; other seeds of the
# same cells stop (docs/reproducing.md).
SEED0_STOPS = {
    ("table3_stop_positions.toml", "clean sign, baseline"): True,
    ("table3_stop_positions.toml", "attacked sign, baseline"): False,
    ("table3_stop_positions.toml", "attacked sign, adjusted"): False,
    ("table3_stop_positions.toml", "attacked sign, side_camera"): False,
    **{("table1_clean_defended.toml", cell): True for cell in DEFENDED_CELLS},
    ("table2_attacked_defended.toml", "Town07 standard"): False,
    ("table2_attacked_defended.toml", "Town03 far"): False,
    ("table2_attacked_defended.toml", "Town03 near"): True,
    ("table2_attacked_defended.toml", "Town10 far"): False,
    ("table2_attacked_defended.toml", "Town10 near"): True,
}


@functools.lru_cache(maxsize=None)
def run_cell(file: str, cell: str, seed: int = SEED) -> RunResult:
    experiment = load_experiment(EXPERIMENTS_DIR / file)
    return run_config(experiment.config_for(experiment.cell(cell), seed))[0]


def _stopping_dist_m(result: RunResult) -> float:
    """The car's measured straight-line stopping distance from the speed at which this run began
    braking, holding the hardest brake command of the run from the first command on [m]."""
    vehicle = VehicleConfig(**result.config["vehicle"])
    road_friction = result.config["scenario"]["road_friction"]
    return brake_test(vehicle, road_friction, result.speed_at_brake_mps, result.max_brake).stop_dist_m


@pytest.mark.parametrize("file,cell", sorted(SEED0_STOPS))
def test_the_seed_0_outcome_follows_from_where_braking_began(file, cell):
    result = run_cell(file, cell)
    stopped = result.stopped_before_sign and result.sign_margin_m > 0
    assert stopped == SEED0_STOPS[file, cell], f"{result.outcome}, {result.sign_margin_m:.2f} m from the sign"
    assert result.dist_at_brake_m is not None, "the policy never braked"
    needed_m = _stopping_dist_m(result)
    if stopped:
        # It stopped, so it began braking at least a stopping distance before the sign.
        assert result.dist_at_brake_m >= needed_m - PHYSICS_TOLERANCE_M
        assert 2.3 <= result.time_to_stop_s <= 3.6  # the study measured 2.55-2.75 s
    else:
        # It ran past because it began braking closer to the sign than the car, at the hardest
        # brake its policy commanded, can stop in: no later command could have saved it.
        assert result.dist_at_brake_m < needed_m + PHYSICS_TOLERANCE_M
        assert result.max_brake >= 0.85  # it did brake hard, as the policy's law says


def test_the_attack_makes_baseline_begin_braking_closer_to_the_sign():
    clean = run_cell("table3_stop_positions.toml", "clean sign, baseline")
    attacked = run_cell("table3_stop_positions.toml", "attacked sign, baseline")
    # Both are seen far beyond the gate; the attack's effect is on the confident frames inside it.
    assert clean.first_detection_dist_m > 60 and attacked.first_detection_dist_m > 60
    assert attacked.dist_at_brake_m < clean.dist_at_brake_m - 1.0
    assert attacked.sign_margin_m < clean.sign_margin_m


def test_autopilot_stops_within_1_5_m_before_the_stop_line():
    result = run_cell("table3_stop_positions.toml", "autopilot")
    assert 0.0 <= result.margin_m <= 1.5
