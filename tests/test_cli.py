"""CLI input errors: one line on stderr, exit code 2, no JSON written, no simulation."""

import pytest

import avsim.loop
from avsim import cli
from avsim.errors import ConfigError


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
    "negative_speed": (["--speed-kmh", "-5"], "speed_kmh"),
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
    assert lines[0].startswith("avsim: error:")
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


# ---- _parse_set ------------------------------------------------------------------------

def test_parse_set_nests_dotted_keys():
    assert cli._parse_set(["policy.baseline_brake=0.9", "policy.name=adjusted", "scenario.seed=3"]) == {
        "policy": {"baseline_brake": 0.9, "name": "adjusted"},
        "scenario": {"seed": 3},
    }


def test_parse_set_deeper_nesting_and_top_level_key():
    assert cli._parse_set(["a.b.c=1", "top=2"]) == {"a": {"b": {"c": 1}}, "top": 2}


@pytest.mark.parametrize(
    "raw, expected, kind",
    [
        ("0.9", 0.9, float),
        ("85.0", 85.0, float),
        ("1e3", 1000.0, float),
        ("3", 3, int),
        ("-2", -2, int),
        ("true", True, bool),
        ("false", False, bool),
        ("town03", "town03", str),
        ('"quoted"', "quoted", str),
        ("textures/faded.png", "textures/faded.png", str),
    ],
)
def test_parse_set_types_values(raw, expected, kind):
    value = cli._parse_set([f"k={raw}"])["k"]
    assert value == expected
    assert type(value) is kind


def test_parse_set_later_value_wins():
    assert cli._parse_set(["policy.name=baseline", "policy.name=adjusted"]) == {"policy": {"name": "adjusted"}}


@pytest.mark.parametrize("item", ["nonsense", "=5", ""])
def test_parse_set_rejects_malformed_items(item):
    with pytest.raises(ConfigError) as excinfo:
        cli._parse_set([item])
    assert "\n" not in str(excinfo.value)
    assert "KEY=VALUE" in str(excinfo.value)


def test_set_overrides_flag_values():
    args = cli.build_parser().parse_args(["run", "--speed-kmh", "50", "--set", "scenario.speed_kmh=60", "--policy", "adjusted"])
    config = cli._config_from_args(args)
    assert config.scenario.speed_kmh == 60.0
    assert config.policy.name == "adjusted"
