"""The command-line error boundary (`avsim.boundary`): one line per outcome, warnings included."""

from __future__ import annotations

import warnings

from avsim.boundary import run_guarded
from avsim.errors import ConfigError


def test_a_warning_beside_a_refusal_is_dropped_and_after_success_is_one_line(capsys):
    def refused() -> int:
        warnings.warn("a library's note\nover two lines", UserWarning, stacklevel=1)
        raise ConfigError("bad value")

    assert run_guarded(refused, prog="p") == 2
    assert capsys.readouterr().err.splitlines() == ["p: error: bad value"]

    def succeeded() -> int:
        warnings.warn("a library's note\nover two lines", UserWarning, stacklevel=1)
        return 0

    assert run_guarded(succeeded, prog="p") == 0
    assert capsys.readouterr().err.splitlines() == ["p: warning: a library's note over two lines"]
