"""User-facing errors.

Every error a user can cause by bad input derives from `AvsimError`. The CLI prints
its message as one line and exits with `exit_code`, so each message names the
problem and the fix in a single sentence.
"""


class AvsimError(Exception):
    """A problem the user can fix; printed as one line by the CLI."""

    exit_code = 2


class ConfigError(AvsimError):
    """Unknown key, bad value, or unknown registry name in a configuration."""


class TextureError(AvsimError):
    """A sign texture that is missing, not a PNG, or of the wrong shape."""


class RenderError(AvsimError):
    """The offscreen OpenGL backend (EGL or OSMesa) could not be started."""


class PhysicsError(AvsimError):
    """The simulation diverged (NaN or runaway state); the run is ended."""

    exit_code = 3


class OutputError(AvsimError):
    """An output path that cannot be written (a folder, a read-only place, an empty name), or a write that failed."""


class RunsFailedError(AvsimError):
    """Every run of a batch failed: the report says so, and the command exits non-zero."""

    exit_code = 1


class Interrupted(AvsimError):
    """Ctrl-C (SIGINT) stopped a command; the message says what is kept and how to resume."""

    exit_code = 130  # 128 + SIGINT, as a shell reports a command stopped by Ctrl-C
