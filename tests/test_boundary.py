"""The command-line error boundary (`avsim.boundary`): one line per outcome, warnings included."""

from __future__ import annotations

import warnings

import mujoco

from avsim.boundary import run_guarded
from avsim.errors import ConfigError
from avsim.library_output import route_mujoco_warnings_to_log


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


def test_mujoco_instability_warnings_are_counted_but_not_printed(capfd):
    route_mujoco_warnings_to_log()
    model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/><geom size="1"/></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    data.qvel[:] = float("nan")
    mujoco.mj_step(model, data)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1  # what the loop's PhysicsError reads
    captured = capfd.readouterr()
    assert "WARNING" not in captured.err and "WARNING" not in captured.out
