"""`avsim run --rrd` onto a full disk (a file-size limit stands in for it): one line, exit 2, and
neither the recording nor its temporary file is left."""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _limit_file_size(max_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
    return apply


@pytest.mark.slow  # about 15 s: one short oracle run in a subprocess
def test_a_recording_that_hits_the_disk_limit_is_one_line_and_leaves_nothing(tmp_path):
    argv = [sys.executable, "-m", "avsim", "run", "--perception", "oracle", "--set", "scenario.start_dist_m=100",
            "--rrd", str(tmp_path / "a.rrd"), "--json", str(tmp_path / "a.json")]
    proc = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, timeout=300, preexec_fn=_limit_file_size(200_000))
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "cannot write" in lines[0] and "a.rrd" in lines[0] and "File too large" in lines[0]
    assert list(tmp_path.iterdir()) == []
