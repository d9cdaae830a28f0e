"""Test helpers importable from any test module (`from helpers import make_config`).

They live outside conftest.py because a second conftest (tests/perception/detector/)
would shadow a `from helpers import ...`.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import pytest

from avsim.config import SimConfig, with_overrides
from avsim.experiments.run_task import RunSpec
from avsim.perception.cpu_bf16 import onednn_runs_bf16

# A test of bf16 arithmetic itself (its agreement with fp32, its batch invariance) runs only where oneDNN
# has bf16 kernels; elsewhere "auto" runs fp32, which the other tests cover.
needs_bf16 = pytest.mark.skipif(not onednn_runs_bf16(), reason="this CPU has no oneDNN bf16 kernels (AVX-512); "
                                                               "its networks run fp32, tested elsewhere")

# Short oracle runs: the sign is in range within a second, the car stops in a few.
SHORT_RUN = {"speed_kmh": 40.0, "start_speed_kmh": 40.0, "start_dist_m": 50.0}

# A whole approach at the study's 85 km/h without the study's start (from rest 230 m out): the car cruises from
# 150 m out, beyond where the oracle (100 m) or the own detector (86-122 m for the clean sign) first reports the
# sign, so a run holds every frame from before the first box to the stop at about half the study start's cost.
CRUISE_START = {"start_dist_m": 150.0, "start_speed_kmh": 85.0}


def make_config(**sections) -> SimConfig:
    """SimConfig with per-section overrides, e.g. make_config(scenario={"town": "town03"}).

    Tests use the `oracle` perception unless they name another: physics and policy tests
    must not depend on how well the learned detector happens to be trained.
    """
    sections = {**sections, "perception": {"kind": "oracle", **sections.get("perception", {})}}
    return with_overrides(SimConfig(), sections)


def short_run_spec(cell: str, seed: int = 0, **sections) -> RunSpec:
    """A batch spec of a short oracle run (`SHORT_RUN`) at `seed`, with the given config sections."""
    sections.setdefault("scenario", {})
    sections["scenario"] = {**SHORT_RUN, "seed": seed, **sections["scenario"]}
    return RunSpec("short", cell, seed, make_config(**sections))


# ---- `avsim` as a separate process, for signal, lock and disk-limit tests ----------------------

REPO = Path(__file__).resolve().parents[1]
PROCESS_TIMEOUT_S = 120.0


def start_avsim(argv: list[str], stderr: Path) -> subprocess.Popen:
    """`python -m avsim ARGV` in its own process group (so a signal can go to the group, as Ctrl-C
    does), stderr to a file. SIGINT's default action is restored in the child, as a terminal's
    foreground process has it: a test session started in the background ignores SIGINT, and a
    child inherits that."""
    with stderr.open("wb") as err:
        return subprocess.Popen([sys.executable, "-m", "avsim", *argv], cwd=REPO, stdout=subprocess.DEVNULL,
                                stderr=err, start_new_session=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_until(condition: Callable[[], bool], proc: subprocess.Popen, what: str, log: Path,
               timeout_s: float = PROCESS_TIMEOUT_S) -> None:
    """Poll `condition` until true; fail the test (showing `log`) if `proc` exits or time runs out first."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"avsim exited ({proc.returncode}) before {what}:\n{log.read_text()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"not {what} within {timeout_s} s")
        time.sleep(0.02)


def write_files(root: Path, files: Mapping[str, str | bytes], tmp: str) -> None:
    """Make each {relative path: text or bytes} under `root`; "{tmp}" in a text becomes `tmp`."""
    for name, content in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content.replace("{tmp}", tmp))
