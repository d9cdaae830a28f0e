"""MUJOCO_GL checked before MuJoCo is imported: egl and osmesa, or one line naming the fix."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from avsim.errors import RenderError
from avsim.sensors.gl_backend import check_gl_backend, library_loads

REPO = Path(__file__).resolve().parents[2]


def _all_there(name: str) -> bool:
    return True


@pytest.mark.parametrize("value, backend", [({}, "egl"), ({"MUJOCO_GL": "egl"}, "egl"), ({"MUJOCO_GL": " OSMesa "}, "osmesa")])
def test_egl_is_the_default_and_osmesa_the_fallback(value, backend):
    assert check_gl_backend(value, _all_there) == backend


@pytest.mark.parametrize("value", ["nonsense", "glfw", "glx", "", "off"])
def test_any_other_renderer_is_refused_listing_the_valid_ones(value):
    with pytest.raises(RenderError, match="egl .*osmesa") as excinfo:
        check_gl_backend({"MUJOCO_GL": value}, _all_there)
    assert "\n" not in str(excinfo.value)


def test_a_pyopengl_platform_of_another_backend_is_refused():
    with pytest.raises(RenderError, match="unset PYOPENGL_PLATFORM"):
        check_gl_backend({"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "egl"}, _all_there)


@pytest.mark.parametrize("backend, package", [("osmesa", "libosmesa6"), ("egl", "libegl1")])
def test_a_missing_library_names_the_debian_package(backend, package):
    with pytest.raises(RenderError, match=f"apt-get install {package}"):
        check_gl_backend({"MUJOCO_GL": backend}, lambda name: False)


@pytest.mark.skipif(not library_loads("OSMesa"), reason="libosmesa6 is not installed (`.ci/run` installs it as root)")
def test_osmesa_renders_the_same_snapshot_as_egl(tmp_path):
    for backend in ("egl", "osmesa"):
        # This process imported MuJoCo with EGL, which set PYOPENGL_PLATFORM=egl.
        env = {**{k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"}, "MUJOCO_GL": backend}
        subprocess.run([sys.executable, "-m", "avsim", "snapshot", "--out", str(tmp_path / backend)], cwd=REPO, env=env,
                       check=True, capture_output=True)
    egl, osmesa = (cv2.imread(str(tmp_path / f"{b}_front.png")) for b in ("egl", "osmesa"))
    assert egl is not None and osmesa is not None
    assert np.array_equal(egl, osmesa)
