"""What a Ray cluster's runs ran on (`avsim.experiments.ray_backend.cluster_nodes`): each node's versions in
the manifest, and a warning where a node is not this machine's twin."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from avsim.experiments import ray_backend
from avsim.experiments.sweep import load_sweep, run_sweep
from avsim.software import software_versions

SMOKE = Path(__file__).resolve().parents[2] / "experiments" / "sweeps" / "sweep_smoke.toml"


def test_runs_on_this_machine_ask_no_node():
    # The local backend and a local Ray cluster run on this machine: the manifest's `versions` says what.
    assert ray_backend.cluster_nodes("local", None) is None
    assert ray_backend.cluster_nodes("ray", None) is None


def test_a_node_unlike_this_machine_is_a_warning_and_every_node_is_kept(monkeypatch):
    here = software_versions()
    nodes = [{"node": "10.0.0.2", **here}, {"node": "10.0.0.3", **here, "gl": "another GL"}]
    monkeypatch.setattr(ray_backend, "node_versions", lambda address: nodes)
    with pytest.warns(UserWarning) as caught:
        assert ray_backend.cluster_nodes("ray", "10.0.0.1:6379") == nodes
    (message,) = [str(w.message) for w in caught]
    assert message.startswith("the Ray cluster at 10.0.0.1:6379 is not this machine's twin: 10.0.0.3 runs gl 'another GL'")
    assert "10.0.0.2" not in message
    monkeypatch.setattr(ray_backend, "node_versions", lambda address: nodes[:1])
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message="the Ray cluster")  # a twin says nothing
        assert ray_backend.cluster_nodes("ray", "10.0.0.1:6379") == nodes[:1]


def test_a_cluster_with_no_node_to_ask_is_a_warning(monkeypatch):
    monkeypatch.setattr(ray_backend, "node_versions", lambda address: [])
    with pytest.warns(UserWarning, match="had no node with CPUs when asked"):
        assert ray_backend.cluster_nodes("ray", "10.0.0.1:6379") == []


@pytest.mark.slow  # 20 s: starts a local Ray cluster
@pytest.mark.usefixtures("one_local_ray_cluster_at_a_time")
def test_a_sweep_at_an_address_records_what_each_node_runs(tmp_path):
    ray = pytest.importorskip("ray")
    from avsim.experiments.run_task import worker_env

    # The cluster "auto" finds is the one this process joined: here a local one, started as a node starts it.
    ray.init(num_cpus=2, include_dashboard=False, runtime_env={"env_vars": worker_env(2)})
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("error", message="the Ray cluster")  # its one node is this machine
            out = run_sweep(load_sweep(SMOKE), tmp_path / "on_cluster", progress=False, backend="ray", address="auto")
    finally:
        ray.shutdown()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["failed"] == 0 and manifest["address"] == "auto"
    (node,) = manifest["cluster_nodes"]
    assert node.pop("node") == ray.util.get_node_ip_address()
    assert node == manifest["versions"] == software_versions()  # read on the node, in a Ray worker process
    assert "They ran on 1 Ray node (manifest.json's cluster_nodes): each with these versions." in (
        out / "summary.md").read_text()
