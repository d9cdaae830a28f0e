"""Which offscreen OpenGL back-end MuJoCo will use, checked before MuJoCo is imported.

MuJoCo reads MUJOCO_GL once, when `import mujoco` runs, and fails there: an unknown value is
a RuntimeError, and `osmesa` without the OSMesa library an AttributeError from deep inside
PyOpenGL. `check_gl_backend` turns both into one line that names the fix. It imports nothing
of MuJoCo, so the CLI calls it first.

avsim renders offscreen only. `egl` (the default) and `osmesa` work without a display;
`glfw` and `glx` need an X display and a window, so they are refused too.
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Callable, Mapping

from avsim.errors import RenderError

DEFAULT_BACKEND = "egl"
# Back-end -> (the shared library PyOpenGL loads for it, the Debian package that installs it).
BACKENDS = {"egl": ("EGL", "libegl1"), "osmesa": ("OSMesa", "libosmesa6")}


def library_loads(name: str) -> bool:
    """Whether lib<name>.so can be loaded, tried under the file names PyOpenGL tries."""
    base = f"lib{name}.so"
    for filename in (base, *(f"{base}.{i}" for i in range(9, -1, -1))):
        try:
            ctypes.CDLL(filename)
            return True
        except OSError:
            continue
    return False


def check_gl_backend(environ: Mapping[str, str] | None = None, loads: Callable[[str], bool] | None = None) -> str:
    """The back-end MUJOCO_GL names (default egl); a one-line RenderError when avsim cannot use it.

    environ: default os.environ; loads: whether a shared library can be loaded (default
    `library_loads`; tests pass a stand-in).
    """
    environ = os.environ if environ is None else environ
    loads = library_loads if loads is None else loads
    value = environ.get("MUJOCO_GL", DEFAULT_BACKEND)
    backend = value.strip().lower()
    valid = ", ".join(f"{name} (Debian package {package})" for name, (_, package) in BACKENDS.items())
    if backend not in BACKENDS:
        raise RenderError(f"MUJOCO_GL={value!r} is not an offscreen renderer avsim can use; set MUJOCO_GL to one of: {valid}")
    # MuJoCo's back-ends set PyOpenGL's platform to their own name, and refuse another one.
    platform = environ.get("PYOPENGL_PLATFORM", backend).strip().lower()
    if platform != backend:
        raise RenderError(f"PYOPENGL_PLATFORM={platform} conflicts with MUJOCO_GL={backend}; unset PYOPENGL_PLATFORM "
                          f"or set it to {backend}")
    library, package = BACKENDS[backend]
    if not loads(library):
        raise RenderError(f"MUJOCO_GL={backend} needs lib{library}, which is not installed: apt-get install {package}"
                          + ("" if backend == DEFAULT_BACKEND else f", or use MUJOCO_GL={DEFAULT_BACKEND}"))
    return backend
