"""Shared helpers: cached closed-loop runs so several tests can assert on one run."""

from __future__ import annotations

import functools
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from avsim.runner import run_config  # noqa: E402
from avsim.metrics import RunResult  # noqa: E402
from helpers import make_config  # noqa: E402


@functools.lru_cache(maxsize=None)
def _cached_run(town: str, placement: str, policy: str, seed: int, perception: str, sign: str) -> RunResult:
    config = make_config(scenario={"town": town, "placement": placement, "seed": seed, "sign": sign},
                         policy={"name": policy}, perception={"kind": perception})
    return run_config(config)[0]


@pytest.fixture
def study_run():
    """run(town, placement, policy, seed=0, perception="oracle", sign="clean") -> RunResult at 85 km/h,
    cached for the session so several tests can assert on one run."""
    return lambda town, placement, policy, seed=0, perception="oracle", sign="clean": _cached_run(
        town, placement, policy, seed, perception, sign)
