"""`import avsim` sets libgomp's spin count before torch loads it, and leaves a user's own choice alone."""

import os
import subprocess
import sys

import pytest


def _libgomp_settings(extra_env: dict[str, str]) -> str:
    """What libgomp reports at load (OMP_DISPLAY_ENV) when a process imports avsim's detector, then torch."""
    env = {key: value for key, value in os.environ.items() if key not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    env.update(extra_env, OMP_DISPLAY_ENV="VERBOSE")
    done = subprocess.run([sys.executable, "-c", "import avsim.perception.detector.infer"],
                          env=env, capture_output=True, text=True, timeout=120, check=True)
    return done.stderr


def test_importing_avsim_gives_libgomp_a_short_spin():
    assert "GOMP_SPINCOUNT = '1000'" in _libgomp_settings({})


@pytest.mark.parametrize("user_env, expected", [
    ({"GOMP_SPINCOUNT": "50"}, "GOMP_SPINCOUNT = '50'"),
    ({"OMP_WAIT_POLICY": "ACTIVE"}, "OMP_WAIT_POLICY = 'ACTIVE'"),
])
def test_a_users_own_openmp_wait_setting_wins(user_env, expected):
    settings = _libgomp_settings(user_env)
    assert expected in settings
    if "OMP_WAIT_POLICY" in user_env:
        assert "GOMP_SPINCOUNT = '1000'" not in settings
