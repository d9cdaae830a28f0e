"""The study's claims as physics assertions, on the shipped experiment files at 85 km/h.

Each test runs one cell of `experiments/*.toml` exactly as `avsim reproduce` (and
`avsim run --config FILE --cell NAME --seed 0`) runs it: detector perception on the rendered
frames, seed 0's start jitter and lighting. `avsim reproduce` runs every seed and reports
the cells where an outcome differs between seeds; these tests pin seed 0.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from avsim.experiments import load_experiment
from avsim.loop import run_config
from avsim.metrics import RunResult

EXPERIMENTS_DIR = Path(__file__).resolve().parents[2] / "experiments"
SEED = 0
DEFENDED_CELLS = ("Town07 standard", "Town03 far", "Town03 near", "Town10 far", "Town10 near")

pytestmark = pytest.mark.slow


@functools.lru_cache(maxsize=None)
def run_cell(file: str, cell: str, seed: int = SEED) -> RunResult:
    experiment = load_experiment(EXPERIMENTS_DIR / file)
    return run_config(experiment.config_for(experiment.cell(cell), seed))[0]


def _stopped_before_sign(result: RunResult) -> bool:
    return result.stopped_before_sign and result.sign_margin_m > 0


def test_clean_sign_baseline_stops_before_the_sign():
    result = run_cell("table3_stop_positions.toml", "clean sign, baseline")
    assert _stopped_before_sign(result), f"{result.outcome}, {result.sign_margin_m:.2f} m"


def test_strongest_attacked_sign_makes_baseline_run_past_the_sign():
    result = run_cell("table3_stop_positions.toml", "attacked sign, baseline")
    clean = run_cell("table3_stop_positions.toml", "clean sign, baseline")
    assert result.sign_margin_m < 0, f"stopped {result.sign_margin_m:.2f} m before the sign"
    assert result.first_detection_dist_m < clean.first_detection_dist_m  # the attack is why: a later detection


@pytest.mark.parametrize("cell", ["attacked sign, adjusted", "attacked sign, side_camera"])
def test_each_defence_stops_before_the_attacked_sign(cell):
    result = run_cell("table3_stop_positions.toml", cell)
    assert _stopped_before_sign(result), f"{result.outcome}, {result.sign_margin_m:.2f} m"


def test_autopilot_stops_within_1_5_m_before_the_stop_line():
    result = run_cell("table3_stop_positions.toml", "autopilot")
    assert 0.0 <= result.margin_m <= 1.5


# Where both defences cannot hold at seed 0 (`avsim reproduce` reports every seed): the
# yang texture hides the sign from both cameras until it is closer than the car's full-brake
# stopping distance from 85 km/h (v²/2a = 23.6²/(2 × 8.6) = 32.5 m), so no braking law can
# stop the car before it. The assertion is on that physics, not on a stop.
OUT_OF_REACH = {("table2_attacked_defended.toml", "Town10 far")}
DEFENDED = [(file, cell) for file in ("table1_clean_defended.toml", "table2_attacked_defended.toml") for cell in DEFENDED_CELLS]


@pytest.mark.parametrize("file,cell", [fc for fc in DEFENDED if fc not in OUT_OF_REACH])
def test_both_defences_stop_before_the_sign_in_2_3_to_3_2_s(file, cell):
    result = run_cell(file, cell)
    assert _stopped_before_sign(result), f"{result.outcome}, {result.sign_margin_m:.2f} m"
    assert 2.3 <= result.time_to_stop_s <= 3.2  # the study measured 2.55-2.75 s


@pytest.mark.parametrize("file,cell", sorted(OUT_OF_REACH))
def test_where_both_defences_fail_the_sign_was_first_seen_inside_the_stopping_distance(file, cell):
    result = run_cell(file, cell)
    assert result.sign_margin_m < 0, "it now stops before the sign: move the cell back to the test above"
    assert result.mean_decel_mps2 >= 8.4  # the defences braked as hard as the car can
    stopping_dist_m = result.speed_at_brake_mps ** 2 / (2 * result.mean_decel_mps2)
    assert result.first_detection_dist_m < stopping_dist_m
    assert 2.3 <= result.time_to_stop_s <= 3.2
