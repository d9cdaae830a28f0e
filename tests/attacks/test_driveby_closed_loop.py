"""The shipped drive-by texture in the closed loop, at a fixed seed, with the physics of the outcome.

Seed 0 of Table III's attacked `baseline` cell (Town07 standard, 85 km/h, the 40 m gate, sensor
noise and lighting of seed 0) with `driveby_detector` in place of `yang`. Over 20 seeds it runs
past in all 20 (`experiments/attacks/driveby_detector_town07.toml`), seed 0 among them.
"""

from pathlib import Path

import pytest

from avsim.config import VehicleConfig, with_overrides
from avsim.experiments import load_experiment
from avsim.runner import run_config
from avsim.vehicle.brake_test import brake_test

EXPERIMENTS_DIR = Path(__file__).resolve().parents[2] / "experiments"


@pytest.mark.slow
def test_driveby_detector_makes_baseline_run_past_at_seed_0_because_braking_began_inside_its_stopping_distance():
    experiment = load_experiment(EXPERIMENTS_DIR / "table3_stop_positions.toml")
    clean_config = experiment.config_for(experiment.cell("clean sign, baseline"), 0)
    attacked_config = with_overrides(clean_config, {"scenario": {"sign": "driveby_detector"}})
    clean, attacked = run_config(clean_config)[0], run_config(attacked_config)[0]

    assert clean.stopped_before_sign and not attacked.stopped_before_sign, attacked.outcome
    assert attacked.outcome == "ran_past_sign"
    # The attack's effect: braking began later than for the clean sign, on the same seed.
    assert attacked.dist_at_brake_m < clean.dist_at_brake_m - 3.0
    # The physics: from there the car, at the brake the policy latched, needs more road than was left.
    stop = brake_test(VehicleConfig(**attacked.config["vehicle"]), attacked.config["scenario"]["road_friction"],
                      attacked.speed_at_brake_mps, attacked.max_brake)
    assert attacked.dist_at_brake_m < stop.stop_dist_m
    assert attacked.sign_margin_m == pytest.approx(attacked.dist_at_brake_m - stop.stop_dist_m, abs=0.6)
