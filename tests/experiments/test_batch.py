"""Batches of runs: records, traces, failure isolation, and the same results in worker processes."""

import numpy as np
import pytest

from avsim.errors import ConfigError
from avsim.experiments.batch import RunSpec, config_hash, execute, failed_record, run_batch, worker_env
from avsim.loop import run_config
from avsim.world.textures import save_texture_png
from helpers import make_config

# Short oracle runs: the sign is in range within a second, the car stops in a few.
SHORT = {"speed_kmh": 40.0, "start_speed_kmh": 40.0, "start_dist_m": 50.0}


def _spec(cell: str, seed: int = 0, **sections) -> RunSpec:
    sections.setdefault("scenario", {})
    sections["scenario"] = {**SHORT, "seed": seed, **sections["scenario"]}
    return RunSpec("short", cell, seed, make_config(**sections))


def test_config_hash_is_stable_and_tells_configs_apart():
    assert config_hash(make_config()) == config_hash(make_config())
    assert config_hash(make_config()) != config_hash(make_config(scenario={"seed": 1}))


def test_a_texture_made_again_under_the_same_name_changes_the_hash(tmp_path):
    # --resume reuses a run by its hash; a config names its texture, so the pixels must count too.
    texture = tmp_path / "remade.png"
    rgb = np.full((64, 64, 3), 200, np.uint8)
    save_texture_png(texture, rgb)
    config = make_config(scenario={"sign": str(texture)})
    before = config_hash(config)
    assert config_hash(config) == before
    rgb[10:20, 10:20] = 0
    save_texture_png(texture, rgb)
    assert config_hash(config) != before
    # A sign-free road has no texture to hash, and hashes as before.
    assert config_hash(make_config(scenario={"sign": "none"})) == config_hash(make_config(scenario={"sign": "none"}))


def test_a_record_holds_the_result_and_a_trace_per_camera_the_policy_renders():
    record = execute(_spec("side", policy={"name": "side_camera"}))
    assert record["status"] == "ok" and record["error"] is None
    direct, _ = run_config(_spec("side", policy={"name": "side_camera"}).config)
    assert record["result"] == direct.to_json_dict()
    trace = record["trace"]
    assert set(trace) == {"sign_dist_m", "speed_mps", "brake", "front_conf", "side_conf"}
    assert len({len(series) for series in trace.values()}) == 1
    assert trace["sign_dist_m"][0] == pytest.approx(SHORT["start_dist_m"] + 1.0, abs=2.5)  # jitter; sign 1 m past the line
    assert max(trace["front_conf"]) == 1.0  # the oracle is certain
    assert trace["brake"][-1] > 0


def test_the_autopilot_trace_has_no_camera_series():
    record = execute(_spec("auto", policy={"name": "autopilot"}))
    assert set(record["trace"]) == {"sign_dist_m", "speed_mps", "brake"}


def test_a_run_that_raises_is_a_failed_record_and_the_batch_goes_on(tmp_path):
    specs = [_spec("bad", scenario={"sign": str(tmp_path / "missing.png")}), _spec("good")]
    seen = []
    records = run_batch(specs, workers=1, on_record=seen.append, progress=False)
    assert [r["status"] for r in records] == ["failed", "ok"]
    assert "missing.png" in records[0]["error"] and records[0]["result"] is None
    assert len(seen) == 2
    # A worker that died (ray backend) is recorded in the same shape.
    assert failed_record(specs[0], "WorkerCrashedError: x").keys() == records[0].keys()


@pytest.mark.parametrize("backend, address, workers, expected", [
    ("dask", None, 1, "unknown backend 'dask'"),
    ("local", "auto", 1, "needs the ray backend"),
    ("local", None, 0, "the local backend needs workers >= 1"),
])
def test_a_bad_backend_is_one_line_before_any_run(backend, address, workers, expected):
    with pytest.raises(ConfigError, match=expected) as info:
        run_batch([_spec("never")], workers=workers, backend=backend, address=address, progress=False)
    assert "\n" not in str(info.value)


def test_worker_processes_give_the_records_of_one_process():
    specs = [_spec("baseline", seed, policy={"name": "baseline"}) for seed in (0, 1)]
    in_process = run_batch(specs, workers=1, progress=False)
    pooled = run_batch(specs, workers=2, progress=False)
    strip = lambda records: [{k: v for k, v in r.items() if k != "wall_s"} for r in records]  # noqa: E731
    assert strip(pooled) == strip(in_process)
    assert in_process[0]["result"] != in_process[1]["result"]  # the seeds really differ


def test_each_worker_renders_on_its_share_of_the_cores(monkeypatch):
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    assert worker_env(2) == {"LP_NUM_THREADS": "2"}
    assert worker_env(8) == {"LP_NUM_THREADS": "1"}
    monkeypatch.setenv("LP_NUM_THREADS", "3")  # the user's own setting wins
    assert worker_env(2) == {}
