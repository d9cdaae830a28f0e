"""One run of a batch: its spec's hash, its record and trace, and its worker's share of the cores."""

import numpy as np
import pytest

from avsim.experiments.run_task import config_hash, execute, worker_env
from avsim.runner import run_config
from avsim.world.textures import save_texture_png
from helpers import SHORT_RUN, make_config, short_run_spec


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
    record = execute(short_run_spec("side", policy={"name": "side_camera"}))
    assert record["status"] == "ok" and record["error"] is None
    direct, _ = run_config(short_run_spec("side", policy={"name": "side_camera"}).config)
    assert record["result"] == direct.to_json_dict()
    trace = record["trace"]
    assert set(trace) == {"sign_dist_m", "speed_mps", "brake", "front_conf", "side_conf"}
    assert len({len(series) for series in trace.values()}) == 1
    assert trace["sign_dist_m"][0] == pytest.approx(SHORT_RUN["start_dist_m"] + 1.0, abs=2.5)  # jitter; sign 1 m past the line
    assert max(trace["front_conf"]) == 1.0  # the oracle is certain
    assert trace["brake"][-1] > 0


def test_the_autopilot_trace_has_no_camera_series():
    record = execute(short_run_spec("auto", policy={"name": "autopilot"}))
    assert set(record["trace"]) == {"sign_dist_m", "speed_mps", "brake"}


def test_each_worker_renders_on_its_share_of_the_cores(monkeypatch):
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    assert worker_env(2) == {"LP_NUM_THREADS": "2"}
    assert worker_env(8) == {"LP_NUM_THREADS": "1"}
    monkeypatch.setenv("LP_NUM_THREADS", "3")  # the user's own setting wins
    assert worker_env(2) == {}
