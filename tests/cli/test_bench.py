"""`avsim bench`: what the command sets up before it measures."""

import os

from avsim.cli.command import main


def test_the_profile_renders_in_the_runs_own_thread_unless_the_user_says_otherwise(monkeypatch):
    seen = []
    monkeypatch.setattr("avsim.bench.profile.run_profile", lambda quick: seen.append(os.environ.get("LP_NUM_THREADS")))
    monkeypatch.setattr("avsim.sensors.gl.check_offscreen_rendering", lambda: seen.append("checked"))
    monkeypatch.delenv("LP_NUM_THREADS", raising=False)
    assert main(["bench", "--profile"]) == 0
    monkeypatch.setenv("LP_NUM_THREADS", "2")
    assert main(["bench", "--profile"]) == 0
    assert seen == ["checked", "0", "checked", "2"]
