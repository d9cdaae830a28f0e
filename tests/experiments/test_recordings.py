"""Recordings on request: `--rrd none|failed|all` in a batch, and recording any run afterwards."""

import dataclasses
import importlib.util
import json
from pathlib import Path

import pytest

from avsim import cli
from avsim.cli.recording_modes import RECORD_CHOICES
from avsim.config import SimConfig
from avsim.errors import ConfigError
from avsim.experiments.failures import is_failed_run
from avsim.experiments.recordings import RECORD_MODES, check_modes, recording_flags, with_recordings
from avsim.experiments.reproduce import reproduce
from avsim.experiments.results_file import read_records
from avsim.experiments.run_task import RunSpec
from avsim.metrics import RunResult

# Oracle perception, short runs. With its braking gate at 3 m the baseline would brake far too late
# at 40 km/h (the sign leaves the view first): it runs past the sign, a failed car found by physics.
TWO_CELLS = """
title = "stops and runs past"
seeds = 2
[defaults]
scenario = { town = "town07", placement = "standard", speed_kmh = 40, start_speed_kmh = 40, start_dist_m = 45 }
perception = { kind = "oracle" }
[[cells]]
name = "stops"
policy = { name = "baseline" }
[[cells]]
name = "runs past"
policy = { name = "baseline", trigger_dist_m = 3 }
"""


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    root = tmp_path_factory.mktemp("recordings")
    experiment = root / "two_cells.toml"
    experiment.write_text(TWO_CELLS)
    mcap = "all" if importlib.util.find_spec("rosbags") else "none"  # bags need avsim[ros]
    out = reproduce(root / "results", workers=1, experiment_paths=[experiment], progress=False, rrd="failed", mcap=mcap)
    return experiment, out, read_records(out / "runs.jsonl")


def test_rrd_failed_records_exactly_the_runs_whose_car_failed_beside_mcap_all(batch):
    _, out, records = batch
    outcomes = {(r["cell"], r["seed"]): r["result"]["outcome"] for r in records}
    assert {outcomes["stops", k] for k in (0, 1)} == {"stopped_before_line"}, outcomes
    assert {outcomes["runs past", k] for k in (0, 1)} <= {"ran_past_sign", "never_braked"}, outcomes
    for r in records:
        failed = is_failed_run(RunResult(**r["result"]))
        assert failed == (r["cell"] == "runs past")
        assert (r["rrd"] is not None) == failed
        assert (r["mcap"] is not None) == (importlib.util.find_spec("rosbags") is not None)  # --mcap all
    for kind in ("rrd", "mcap"):
        written = sorted(p.relative_to(out).as_posix() for p in out.glob(f"{kind}/**/*") if p.is_file())
        assert written == sorted(r[kind] for r in records if r[kind])
    assert all((out / r["rrd"]).stat().st_size > 10_000 for r in records if r["rrd"])


@pytest.mark.parametrize("source", ["experiment", "results"])
def test_a_run_recorded_afterwards_gives_the_same_result_record(batch, tmp_path, source):
    experiment, out, records = batch
    target = next(r for r in records if r["cell"] == "stops" and r["seed"] == 1)  # not recorded by the batch
    assert target["rrd"] is None
    config = str(experiment if source == "experiment" else out / "runs.jsonl")
    rrd, result_json = tmp_path / "again.rrd", tmp_path / "again.json"
    # With avsim[ros], the batch wrote a bag of every run: made again (under the same name, which the
    # bag holds), it is the very file the batch wrote (issue 30's bag of a run that has already run).
    bag = tmp_path / Path(target["mcap"]).name if target["mcap"] else None
    code = cli.main(["run", "--config", config, "--cell", "stops", "--seed", "1", "--rrd", str(rrd), "--json", str(result_json),
                     *(["--mcap", str(bag)] if bag else [])])
    assert code == 0 and rrd.stat().st_size > 10_000
    assert json.loads(result_json.read_text()) == target["result"]
    if bag:
        assert bag.read_bytes() == (out / target["mcap"]).read_bytes()


def test_rrd_all_and_none(tmp_path):
    spec = RunSpec("e", "a cell, b", 3, SimConfig())
    assert list(with_recordings([spec], tmp_path, rrd="none")) == [spec]
    (recorded,) = with_recordings([spec], tmp_path, rrd="all", mcap="all")
    assert (recorded.rrd_when, recorded.mcap_when) == ("all", "all")
    assert recorded.rrd_path == str(tmp_path / "rrd" / "e" / "a_cell_b__seed3.rrd")
    assert recorded.mcap_path == str(tmp_path / "mcap" / "e" / "a_cell_b__seed3.mcap")
    # Two configs under one label get the config hash in their names, so no file is written twice.
    other = dataclasses.replace(spec, config=SimConfig(scenario=dataclasses.replace(SimConfig().scenario, speed_kmh=50)))
    paths = [s.rrd_path for s in with_recordings([spec, other], tmp_path, rrd="failed")]
    assert len(set(paths)) == 2


def test_modes_are_checked_in_one_line():
    assert RECORD_MODES == RECORD_CHOICES
    with pytest.raises(ConfigError, match="--rrd must be one of none, failed, all"):
        check_modes("some", "none")
    assert recording_flags("failed", "none") == "" and recording_flags("all", "failed") == " --rrd all --mcap failed"


def test_a_results_file_without_the_run_is_one_line_and_exit_2(batch, tmp_path, capsys):
    _, out, _ = batch
    code = cli.main(["run", "--config", str(out / "runs.jsonl"), "--cell", "nowhere", "--seed", "0",
                     "--rrd", str(tmp_path / "x.rrd")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and 'no run of cell "nowhere"' in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(("outcome", "stop_required", "max_brake", "failed"), [
    ("stopped_before_line", True, 1.0, False), ("stopped_past_line", True, 1.0, False),
    ("ran_past_sign", True, 1.0, True), ("never_braked", True, 0.0, True), ("timed_out_before_sign", True, 0.0, True),
    ("drove_through", False, 0.0, False), ("drove_through", False, 0.5, True), ("phantom_stop", False, 1.0, True),
])
def test_which_outcomes_are_failures(outcome, stop_required, max_brake, failed):
    result = RunResult([0.0, 0.0], [0.0, 0.0], 0.0, None, None, None, 20.0, {}, outcome, 0.0, None, None, 10.0,
                       max_brake=max_brake, stop_required=stop_required)
    assert is_failed_run(result) == failed


@pytest.mark.parametrize(("outcome", "margin_m", "failed"), [
    ("stopped_before_line", 101.0, True),   # braked on something ~135 m out, as the COCO net on Town10's yield sign
    ("stopped_before_line", 40.0, False),   # at the gate itself: braking began inside it
    ("stopped_before_line", 4.9, False),    # the study's stop
    ("ran_past_sign", -3.0, True),
])
def test_a_stop_at_rest_beyond_the_braking_gate_is_a_failure_worth_recording(outcome, margin_m, failed):
    result = RunResult([0.0, 0.0], [0.0, 0.0], margin_m, 3.0, 130.0, 140.0, 23.6, {"policy": {"trigger_dist_m": 40.0}},
                       outcome, margin_m + 1.0, 8.0, 23.6, 20.0, max_brake=1.0)
    assert result.rested_beyond_gate == (margin_m > 40.0)
    assert is_failed_run(result) == failed


def test_a_config_without_a_braking_gate_never_rests_beyond_it():
    result = RunResult([0.0, 0.0], [0.0, 0.0], 101.0, 3.0, 130.0, 140.0, 23.6, {"policy": {"trigger_dist_m": None}},
                       "stopped_before_line", 102.0, 8.0, 23.6, 20.0, max_brake=1.0)
    assert not result.rested_beyond_gate and not is_failed_run(result)
