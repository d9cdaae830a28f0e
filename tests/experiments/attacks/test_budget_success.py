"""The budget sweep's closed loop: the protocol's clean cell with each texture in its place."""

from pathlib import Path

import pytest

from avsim.experiments.attacks import budget_success
from avsim.errors import ConfigError
from avsim.experiments.results_file import read_records

PROTOCOL = Path(__file__).resolve().parents[3] / "experiments" / "attacks" / "success_town07.toml"


def test_a_textures_runs_differ_from_the_clean_ones_only_in_the_sign():
    protocol = budget_success.load_protocol(PROTOCOL)
    plan = budget_success.protocol_specs(protocol, {"clean": "clean", "ssim_floor=0.7": "driveby_detector"})
    specs = list(plan)
    assert len(specs) == plan.size == 2 * protocol.seeds
    clean = {s.seed: s.config.to_dict() for s in specs if s.cell == "clean"}
    attacked = {s.seed: s.config.to_dict() for s in specs if s.cell == "ssim_floor=0.7"}
    assert sorted(clean) == sorted(attacked) == list(range(protocol.seeds))
    for seed, config in attacked.items():
        assert config["scenario"].pop("sign") == "driveby_detector"
        assert clean[seed]["scenario"].pop("sign") == "clean"
        assert config == clean[seed]  # same start, lighting draw, noise seed, policy and perception
    # The lighting is drawn per seed, so the seeds really differ from one another.
    assert clean[0]["scenario"]["sun_azimuth_deg"] != clean[1]["scenario"]["sun_azimuth_deg"]


def test_a_protocol_without_a_clean_cell_is_refused(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text('title = "t"\n[[cells]]\nname = "yang"\nscenario = { sign = "yang" }\n')
    with pytest.raises(ConfigError, match='no cell named "clean"'):
        budget_success.load_protocol(path)


def _result(outcome: str, margin_m: float, brake_dist_m: float | None) -> dict:
    return {"outcome": outcome, "sign_margin_m": margin_m, "dist_at_brake_m": brake_dist_m}


def _fake_batch(outcomes):
    """A run_batch stand-in: each spec's record from outcomes(cell, seed), in spec order."""

    def run_batch(specs, *, on_record, **_):
        records = []
        for spec in specs:
            status, result = outcomes(spec.cell, spec.seed)
            record = {"experiment": spec.experiment, "cell": spec.cell, "seed": spec.seed, "spec_hash": spec.spec_hash,
                      "status": status, "error": None if status == "ok" else "RuntimeError: boom", "result": result}
            on_record(record)
            records.append(record)
        return records

    return run_batch


def test_success_is_counted_per_texture_and_the_delay_paired_by_seed(tmp_path, monkeypatch):
    def outcomes(cell, seed):
        if cell == "clean":
            return "ok", _result("stopped_before_line", 5.0, 40.0 + seed)
        if seed < 3:  # braked 12 m later than the clean sign at the same seed, and ran 4 m past
            return "ok", _result("ran_past_sign", -4.0, 28.0 + seed)
        return "ok", _result("stopped_before_line", 1.0, 35.0 + seed)

    monkeypatch.setattr(budget_success, "run_batch", _fake_batch(outcomes))
    protocol = budget_success.load_protocol(PROTOCOL)
    runs = tmp_path / "runs.jsonl"
    runs.write_text("a line from an earlier sweep\n")
    result = budget_success.closed_loop_success(protocol, {"ssim_floor=0.7": "driveby_detector"}, runs, progress=False)
    assert set(result) == {"clean", "ssim_floor=0.7"}
    assert (result["clean"].past, result["clean"].runs) == (0, protocol.seeds)
    attacked = result["ssim_floor=0.7"]
    assert (attacked.past, attacked.runs) == (3, protocol.seeds)
    assert attacked.overrun_mean_m == pytest.approx(4.0)
    # 3 seeds braked 12 m late, the others 5 m late.
    assert attacked.brake_delay_mean_m == pytest.approx((3 * 12 + (protocol.seeds - 3) * 5) / protocol.seeds)
    assert result["clean"].brake_delay_mean_m is None
    assert len(read_records(runs)) == 2 * protocol.seeds  # replaced, not appended to


def test_a_failed_run_stops_the_sweep_instead_of_shrinking_the_rate(tmp_path, monkeypatch):
    def outcomes(cell, seed):
        return ("failed", None) if (cell, seed) == ("ssim_floor=0.5", 2) else ("ok", _result("stopped_before_line", 5.0, 40.0))

    monkeypatch.setattr(budget_success, "run_batch", _fake_batch(outcomes))
    protocol = budget_success.load_protocol(PROTOCOL)
    with pytest.raises(RuntimeError, match="1 closed-loop runs failed, e.g. ssim_floor=0.5 seed 2"):
        budget_success.closed_loop_success(protocol, {"ssim_floor=0.5": "yang"}, tmp_path / "runs.jsonl", progress=False)
