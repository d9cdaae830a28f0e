"""Crash-safe JSON-lines results: whole lines appended, a torn last line skipped, atomic rewrite;
anything else that is not a run record refused in one line."""

import json

import pytest

from avsim.errors import ConfigError
from avsim.experiments.results_file import JsonlWriter, read_records, rewrite


def record(seed: int, **extra) -> dict:
    """A run record as `avsim.experiments.batch` writes one (a failed run: no result needed)."""
    return {"experiment": "e", "cell": "c", "seed": seed, "spec_hash": f"h{seed}", "status": "failed",
            "error": "X: y", "result": None, **extra}


def ok_record(seed: int, outcome: str, margin_m: float = 2.0, braked_at_m: float | None = 30.0) -> dict:
    result = {"outcome": outcome, "margin_m": margin_m, "sign_margin_m": margin_m + 1.0, "dist_at_brake_m": braked_at_m}
    return {**record(seed), "status": "ok", "error": None, "result": result}


def test_appended_records_read_back_in_order(tmp_path):
    path = tmp_path / "sub" / "runs.jsonl"
    writer = JsonlWriter(path)
    for k in range(3):
        writer.append(record(k, value=k / 3))
    assert read_records(path) == [record(k, value=k / 3) for k in range(3)]
    assert path.read_text().count("\n") == 3


def test_a_torn_last_line_is_skipped_and_the_rest_kept(tmp_path):
    path = tmp_path / "runs.jsonl"
    JsonlWriter(path).append(record(0))
    with path.open("a") as handle:
        handle.write('{"seed": 1, "val')  # a crash in the middle of a write
    assert read_records(path) == [record(0)]


@pytest.mark.parametrize("bad_line, why", [("garbage", "not JSON"), ("[1, 2]", "JSON list"),
                                           ('{"seed": 1}', "key 'experiment'"),
                                           (json.dumps(record(1, status="maybe")), "status 'maybe'")])
def test_a_corrupt_line_in_the_middle_is_an_error_naming_its_number(tmp_path, bad_line, why):
    path = tmp_path / "runs.jsonl"
    path.write_text(json.dumps(record(0)) + "\n" + bad_line + "\n" + json.dumps(record(2)) + "\n")
    with pytest.raises(ConfigError, match=f"line 2 is corrupt.*{why}") as excinfo:
        read_records(path)
    assert "\n" not in str(excinfo.value)


@pytest.mark.parametrize("text", ['{"name": "a stranger"}\n', "id,value\n1,2\n", "\ufeffnot ours\n"])
def test_a_file_that_is_not_avsims_is_refused(tmp_path, text):
    path = tmp_path / "runs.jsonl"
    path.write_text(text)
    with pytest.raises(ConfigError, match="not an avsim results file"):
        read_records(path)


def test_records_with_the_old_outcome_words_read_with_the_new_ones(tmp_path):
    old = [ok_record(0, "stopped_before_sign", margin_m=-0.5), ok_record(1, "stopped_past_sign", margin_m=-3.0),
           ok_record(2, "did_not_stop", margin_m=-45.0, braked_at_m=None),
           ok_record(3, "did_not_stop", margin_m=-5.0), ok_record(4, "did_not_stop", margin_m=60.0, braked_at_m=None),
           ok_record(5, "stopped_before_line")]
    path = tmp_path / "runs.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in old))
    outcomes = [r["result"]["outcome"] for r in read_records(path)]
    assert outcomes == ["stopped_past_line", "ran_past_sign", "never_braked", "ran_past_sign",
                        "timed_out_before_sign", "stopped_before_line"]


def test_missing_file_has_no_records(tmp_path):
    assert read_records(tmp_path / "none.jsonl") == []


def test_nan_is_refused_before_anything_is_written(tmp_path):
    path = tmp_path / "runs.jsonl"
    with pytest.raises(ValueError):
        JsonlWriter(path).append({"x": float("nan")})
    assert not path.exists() or path.read_text() == ""


def test_rewrite_replaces_the_file_whole(tmp_path):
    path = tmp_path / "runs.jsonl"
    JsonlWriter(path).append(record(9))
    rewrite(path, [record(1), record(2)])
    assert [json.loads(line) for line in path.read_text().splitlines()] == [record(1), record(2)]
    assert [p.name for p in tmp_path.iterdir()] == ["runs.jsonl"]  # no temporary file left
