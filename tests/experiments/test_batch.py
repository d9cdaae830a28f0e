"""Batches of runs: failure isolation, backend checks, and the same records in worker processes."""

import pytest

from avsim.errors import ConfigError
from avsim.experiments.batch import run_batch
from avsim.experiments.run_task import failed_record
from helpers import short_run_spec


def test_a_run_that_raises_is_a_failed_record_and_the_batch_goes_on(tmp_path):
    specs = [short_run_spec("bad", scenario={"sign": str(tmp_path / "missing.png")}), short_run_spec("good")]
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
        run_batch([short_run_spec("never")], workers=workers, backend=backend, address=address, progress=False)
    assert "\n" not in str(info.value)


@pytest.mark.slow  # two spawned workers and four runs, about 15 CPU-s: the slow pass, with the other multi-process checks
def test_worker_processes_give_the_records_of_one_process():
    specs = [short_run_spec("baseline", seed, policy={"name": "baseline"}) for seed in (0, 1)]
    in_process = run_batch(specs, workers=1, progress=False)
    pooled = run_batch(specs, workers=2, progress=False)
    strip = lambda records: [{k: v for k, v in r.items() if k != "wall_s"} for r in records]  # noqa: E731
    assert strip(pooled) == strip(in_process)
    assert in_process[0]["result"] != in_process[1]["result"]  # the seeds really differ
