"""A full disk, played by a file-size limit (RLIMIT_FSIZE): results.jsonl keeps whole records
only, the command says so in one line, and a resume afterwards loses nothing that was finished."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from avsim.experiments.results_file import JsonlWriter, encode, read_records

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"


def _limit_file_size(max_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
    return apply


def _record(seed: int) -> dict:
    return {"experiment": "e", "cell": "c", "seed": seed, "spec_hash": f"h{seed}", "status": "failed",
            "error": "x" * 300, "result": None, "trace": None, "rrd": None, "wall_s": 1.0}


APPEND_UNTIL_FULL = """
import sys
from avsim.errors import OutputError
from avsim.experiments.results_file import JsonlWriter
writer = JsonlWriter(sys.argv[1])
for seed in range(100):
    try:
        writer.append({"experiment": "e", "cell": "c", "seed": seed, "spec_hash": f"h{seed}", "status": "failed",
                       "error": "x" * 300, "result": None, "trace": None, "rrd": None, "wall_s": 1.0})
    except OutputError as exc:
        print(seed, exc)
        break
"""


@pytest.mark.parametrize("limit_bytes", [1000, 1500, 2049])
def test_a_write_past_the_limit_is_cut_back_to_the_last_whole_record(tmp_path, limit_bytes):
    path = tmp_path / "results.jsonl"
    proc = subprocess.run([sys.executable, "-c", APPEND_UNTIL_FULL, str(path)], capture_output=True, text=True,
                          timeout=60, preexec_fn=_limit_file_size(limit_bytes))
    assert proc.returncode == 0, proc.stderr
    failed_at, message = proc.stdout.split(" ", 1)
    line_bytes = len(encode(_record(0)))
    assert int(failed_at) == limit_bytes // line_bytes  # the first record that did not fit whole
    assert "File too large" in message and "\n" not in message.strip()
    text = path.read_text()
    assert text.endswith("\n") and len(text) == int(failed_at) * line_bytes  # no torn line
    assert [r["seed"] for r in read_records(path)] == list(range(int(failed_at)))
    JsonlWriter(path).append(_record(99))  # without the limit, appending goes on after the last whole line
    assert read_records(path)[-1]["seed"] == 99


@pytest.mark.slow  # about 45 s: a reference sweep, one stopped by the limit, and its resumption
def test_a_sweep_that_fills_the_disk_stops_in_one_line_and_resumes_to_the_same_records(tmp_path):
    reference = tmp_path / "reference"
    subprocess.run([sys.executable, "-m", "avsim", "sweep", str(SMOKE), "--out", str(reference), "--workers", "1",
                    "--rrd", "none", "--no-progress"], cwd=REPO, check=True, capture_output=True, timeout=300)
    expected = read_records(reference / "results.jsonl")
    # Room for the first two records of results.jsonl and no more (the other files are smaller,
    # except the figure and summary, which are written only once every run is in).
    sizes = [len(line) + 1 for line in (reference / "results.jsonl").read_text().splitlines()]
    limit = sizes[0] + sizes[1] + min(sizes[2], sizes[3]) // 2

    out = tmp_path / "full"
    # --rrd none: this test is about results.jsonl; a recording that meets the limit is test_rerun_disk_full's
    argv = [sys.executable, "-m", "avsim", "sweep", str(SMOKE), "--out", str(out), "--workers", "1", "--rrd", "none",
            "--no-progress"]
    full = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, timeout=300, preexec_fn=_limit_file_size(limit))
    lines = full.stderr.splitlines()
    assert full.returncode == 2 and len(lines) == 1, full.stderr
    assert "File too large" in lines[0] and "2 finished runs" in lines[0] and "--resume" in lines[0]
    text = (out / "results.jsonl").read_text()
    assert text.endswith("\n") and len(read_records(out / "results.jsonl")) == 2  # whole records only
    assert [json.loads(line)["seed"] for line in text.splitlines()] == [0, 0]

    resumed = subprocess.run([*argv, "--resume"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    strip = lambda records: [{k: v for k, v in r.items() if k != "wall_s"} for r in records]  # noqa: E731
    assert strip(read_records(out / "results.jsonl")) == strip(expected)
