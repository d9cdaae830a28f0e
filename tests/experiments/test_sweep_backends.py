"""`avsim sweep --backend ray`: the records of the local pool, and a missing Ray is one line, not a traceback."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from avsim import cli
from avsim.experiments.results_file import read_records
from avsim.experiments.sweep import load_sweep, run_sweep

SMOKE = Path(__file__).resolve().parents[2] / "experiments" / "sweeps" / "sweep_smoke.toml"


def _without_wall_time(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in records]


@pytest.mark.slow  # 20 s: starts a local Ray cluster
@pytest.mark.usefixtures("one_local_ray_cluster_at_a_time")
def test_ray_on_a_local_two_cpu_cluster_gives_the_records_of_the_local_backend(tmp_path):
    pytest.importorskip("ray")
    sweep = load_sweep(SMOKE)
    local = run_sweep(sweep, tmp_path / "local", workers=1, progress=False, batch=1)
    on_ray = run_sweep(sweep, tmp_path / "ray", workers=2, progress=False, backend="ray")  # two lock-step tasks of 2
    local_records, ray_records = read_records(local / "results.jsonl"), read_records(on_ray / "results.jsonl")
    assert [r["status"] for r in ray_records] == ["ok"] * 4
    assert _without_wall_time(ray_records) == _without_wall_time(local_records)
    manifest = json.loads((on_ray / "manifest.json").read_text())
    assert (manifest["backend"], manifest["address"], manifest["workers"], manifest["failed"]) == ("ray", None, 2, 0)
    assert manifest["cluster_nodes"] is None  # a local cluster runs on this machine, which `versions` describes
    assert "--backend ray" in manifest["command"]
    assert "with 2 Ray workers" in (on_ray / "summary.md").read_text()


@pytest.mark.slow  # 10 s: starts a local Ray cluster
@pytest.mark.usefixtures("one_local_ray_cluster_at_a_time")
def test_a_ray_worker_that_dies_is_retried_then_recorded_as_failed_and_the_batch_goes_on(monkeypatch):
    pytest.importorskip("ray")
    from avsim.experiments import batch, ray_backend, run_task

    specs = load_sweep(SMOKE).specs()[:2]
    # Sent to the workers by value (a lambda): the process exits mid-task, as in a segfault or an OOM kill.
    monkeypatch.setattr(ray_backend, "execute_group", lambda specs, root=None: os._exit(1))
    records = batch.run_batch(specs, workers=2, backend="ray", progress=False)
    assert [(r["cell"], r["status"]) for r in records] == [(s.cell, "failed") for s in specs]
    assert all(r["error"].startswith("WorkerCrashedError: ") and "\n" not in r["error"] for r in records)
    assert records[0].keys() == run_task.failed_record(specs[0], "x").keys()


def test_without_ray_the_ray_backend_is_one_line_naming_the_install_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError, installed or not
    out = tmp_path / "out"
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--backend", "ray", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("avsim: error: ") and "\n" not in err
    assert "pip install 'avsim[ray]'" in err
    assert not out.exists()


def test_an_address_without_the_ray_backend_is_rejected_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--address", "auto", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--backend ray" in err
    assert not out.exists()


@pytest.mark.parametrize("address, expected", [("127.0.0.1:1", "no Ray cluster answers at '127.0.0.1:1'"),
                                               ("ray://127.0.0.1:1", "no Ray cluster answers"),
                                               ("nowhere", "must be auto, HOST:PORT or ray://HOST:PORT")])
def test_a_dead_or_malformed_address_is_one_line_before_anything_is_written(tmp_path, capsys, address, expected):
    pytest.importorskip("ray")
    out = tmp_path / "out"
    assert cli.main(["sweep", str(SMOKE), "--out", str(out), "--backend", "ray", "--address", address, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and expected in err
    assert not out.exists()
