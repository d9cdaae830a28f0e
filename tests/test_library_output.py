"""Library printouts kept off the command line (`avsim.library_output`)."""

from __future__ import annotations

import mujoco

from avsim.library_output import route_mujoco_warnings_to_log


def test_mujoco_instability_warnings_are_counted_but_not_printed(capfd):
    route_mujoco_warnings_to_log()
    model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><body><freejoint/><geom size="1"/></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    data.qvel[:] = float("nan")
    mujoco.mj_step(model, data)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1  # what the loop's PhysicsError reads
    captured = capfd.readouterr()
    assert "WARNING" not in captured.err and "WARNING" not in captured.out
