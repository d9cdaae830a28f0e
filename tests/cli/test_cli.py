"""CLI input errors: one line on stderr, exit code 2, no JSON written, no simulation."""

import pytest

import avsim.loop
from avsim import cli
from avsim.cli import command
from avsim.cli.flags import config_from_args


@pytest.fixture
def no_simulation(monkeypatch):
    """Fail the test if the closed loop takes a single step."""

    def _boom(self, *args, **kwargs):
        raise AssertionError("the CLI started simulating before rejecting bad input")

    monkeypatch.setattr(avsim.loop.ClosedLoop, "step", _boom)
    monkeypatch.setattr(avsim.loop.ClosedLoop, "run", _boom)


BAD_ARGS = {
    "unknown_town": (["--town", "town99"], "town99"),
    "unknown_placement": (["--placement", "sideways"], "sideways"),
    "unknown_policy": (["--policy", "brake_never"], "brake_never"),
    "negative_speed": (["--speed-kmh", "-5"], "--speed-kmh: must be in (0, 200] km/h"),
    "dt_not_dividing_control_period": (["--physics-dt-s", "0.003"], "physics_dt_s"),
    "malformed_set": (["--set", "nonsense"], "nonsense"),
    "unknown_set_key": (["--set", "scenario.nope=1"], "scenario.nope"),
    "set_wrong_type": (["--set", "scenario.seed=abc"], "scenario.seed"),
    "unknown_sign_texture": (["--sign", "no_such_texture"], "no_such_texture"),
}


@pytest.mark.parametrize("extra, mention", list(BAD_ARGS.values()), ids=list(BAD_ARGS))
def test_run_bad_input_exits_2_with_one_line_and_no_json(tmp_path, capsys, no_simulation, extra, mention):
    out = tmp_path / "out.json"
    code = cli.main(["run", *extra, "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(("avsim: error:", "avsim run: error:"))  # avsim's checks, or argparse's
    assert mention in lines[0]
    assert captured.out == ""
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_run_conflicting_set_keys_is_a_one_line_error(tmp_path, capsys, no_simulation):
    # A leaf and a section under the same name: malformed, must not crash with a traceback.
    out = tmp_path / "out.json"
    code = cli.main(["run", "--set", "scenario=1", "--set", "scenario.seed=2", "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("avsim: error:")
    assert not out.exists()


def test_snapshot_bad_input_exits_2(tmp_path, capsys, no_simulation):
    code = cli.main(["snapshot", "--town", "town99", "--out", str(tmp_path / "snap")])
    captured = capsys.readouterr()
    assert code == 2
    assert len(captured.err.splitlines()) == 1
    assert captured.err.startswith("avsim: error:")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, mention", [
    (["--strip"], "--towns"),
    (["--towns", "town07,town03"], "--strip"),
    (["--towns", "town07,town99", "--strip"], "town99"),
])
def test_snapshot_strip_bad_input_exits_2_before_rendering(tmp_path, capsys, no_simulation, argv, mention):
    code = cli.main(["snapshot", *argv, "--out", str(tmp_path / "strip")])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and mention in err
    assert list(tmp_path.iterdir()) == []


def test_snapshot_strip_puts_the_towns_front_cameras_side_by_side_at_half_size(tmp_path):
    import cv2

    assert cli.main(["snapshot", "--towns", "town07,town10", "--strip", "--set", "perception.kind=oracle",
                     "--out", str(tmp_path / "strip")]) == 0
    image = cv2.imread(str(tmp_path / "strip.png"))
    assert image.shape == (240, 640, 3)


def test_set_overrides_flag_values():
    args = command.build_parser().parse_args(["run", "--speed-kmh", "50", "--set", "scenario.speed_kmh=60", "--policy", "adjusted"])
    config = config_from_args(args)
    assert config.scenario.speed_kmh == 60.0
    assert config.policy.name == "adjusted"
