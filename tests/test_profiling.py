"""`avsim bench --profile`'s stage timer: it changes no result, its stages add up, and it leaves
nothing wrapped behind."""

import pytest

from avsim.profiling import StageTimer, profile_run
from avsim.runner import run_config
from avsim.vehicle import physics
from helpers import SHORT_RUN, make_config


@pytest.mark.parametrize("perception", ["oracle", "detector"])
def test_a_profiled_run_has_the_unprofiled_result_and_its_stages_add_up(perception, tmp_path):
    config = make_config(scenario=SHORT_RUN, perception={"kind": perception}, loop={"max_time_s": 2.0})
    mujoco_before = physics.mujoco
    profile = profile_run(config, rrd_path=str(tmp_path / "run.rrd"))
    assert profile.result.to_json_dict() == run_config(config)[0].to_json_dict()
    assert profile.steps == 40
    seconds = profile.stage_wall_s
    assert sum(seconds.values()) == pytest.approx(profile.wall_s, rel=1e-6)
    assert sum(profile.stage_cpu_s.values()) == pytest.approx(profile.cpu_s, rel=1e-6)
    assert all(s >= 0 for s in [*seconds.values(), *profile.stage_cpu_s.values()])
    assert seconds["render and read-back"] > 0 and seconds["physics: MuJoCo"] > 0 and seconds["recording"] > 0
    assert ("detector network" in seconds) == (perception == "detector")
    assert physics.mujoco is mujoco_before  # restored
    assert (tmp_path / "run.rrd").is_file()


def test_nested_stages_are_exclusive():
    timer = StageTimer()

    class Work:
        def outer(self):
            return self.inner() + 1

        def inner(self):
            return sum(range(20000))

    work = Work()
    with timer.running():
        timer.wrap(work, "outer", "outer")
        timer.wrap(work, "inner", "inner")
        for _ in range(5):
            work.outer()
    assert timer.calls() == {"outer": 5, "inner": 5}
    assert "outer" not in vars(work) and "inner" not in vars(work)  # the class's methods again
    assert timer.seconds()["inner"] > 0 and timer.seconds()["outer"] >= 0
