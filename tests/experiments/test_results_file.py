"""Crash-safe JSON-lines results: whole lines appended, a torn last line skipped, atomic rewrite."""

import json

import pytest

from avsim.experiments.results_file import JsonlWriter, read_records, rewrite


def test_appended_records_read_back_in_order(tmp_path):
    path = tmp_path / "sub" / "runs.jsonl"
    writer = JsonlWriter(path)
    for k in range(3):
        writer.append({"seed": k, "value": k / 3})
    assert read_records(path) == [{"seed": k, "value": k / 3} for k in range(3)]
    assert path.read_text().count("\n") == 3


def test_a_torn_last_line_is_skipped_and_the_rest_kept(tmp_path):
    path = tmp_path / "runs.jsonl"
    JsonlWriter(path).append({"seed": 0})
    with path.open("a") as handle:
        handle.write('{"seed": 1, "val')  # a crash in the middle of a write
    assert read_records(path) == [{"seed": 0}]


def test_missing_file_has_no_records(tmp_path):
    assert read_records(tmp_path / "none.jsonl") == []


def test_nan_is_refused_before_anything_is_written(tmp_path):
    path = tmp_path / "runs.jsonl"
    with pytest.raises(ValueError):
        JsonlWriter(path).append({"x": float("nan")})
    assert not path.exists() or path.read_text() == ""


def test_rewrite_replaces_the_file_whole(tmp_path):
    path = tmp_path / "runs.jsonl"
    JsonlWriter(path).append({"seed": 9})
    rewrite(path, [{"seed": 1}, {"seed": 2}])
    assert [json.loads(line) for line in path.read_text().splitlines()] == [{"seed": 1}, {"seed": 2}]
    assert [p.name for p in tmp_path.iterdir()] == ["runs.jsonl"]  # no temporary file left
