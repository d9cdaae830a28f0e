"""Every class of bad input or bad environment, through `avsim.cli.main`: the exit status, one line
on stderr, and no output file afterwards.

The simulator must never be built: `no_simulation` makes building a ClosedLoop fail the test, so
every case here is refused before any work, and the table stays fast.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import avsim.loop
from avsim import cli
from avsim.cli import command
from avsim.config import MAX_SEED
from helpers import write_files

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"


@dataclass(frozen=True)
class Case:
    """argv: with {tmp} for the test's folder; mention: a word the one line must contain.

    files: extra files the case needs before it runs, {relative path: text or bytes}.
    """

    argv: list[str]
    mention: str
    status: int = 2
    env: dict[str, str] = field(default_factory=dict)
    files: dict[str, str | bytes] = field(default_factory=dict)


def _record(seed: int) -> str:
    return json.dumps({"experiment": "sweep_smoke", "cell": "c", "seed": seed, "spec_hash": f"h{seed}",
                       "status": "failed", "error": "X: y", "result": None}) + "\n"


SWEEP = "title = 't'\n[defaults]\nperception = { kind = 'oracle' }\n[grid]\n"
ORACLE = ["--perception", "oracle"]

CASES = {
    # ---- output paths: every command, before any work -------------------------------------------------------
    "run --json a folder": Case(["run", *ORACLE, "--json", "{tmp}/adir"], "is a folder", files={"adir/keep": ""}),
    "run --json ''": Case(["run", *ORACLE, "--json", ""], "needs a file name"),
    "run --rrd ''": Case(["run", *ORACLE, "--rrd", ""], "needs a file name"),
    "run --json in /proc": Case(["run", *ORACLE, "--json", "/proc/x.json"], "cannot write in /proc"),
    "run --json /dev/null": Case(["run", *ORACLE, "--json", "/dev/null"], "not a regular file"),
    "run --json under a file": Case(["run", *ORACLE, "--json", "{tmp}/afile/x.json"], "is a file", files={"afile": "x"}),
    "run --json a folder, --rrd and --mp4 fine": Case(
        ["run", *ORACLE, "--rrd", "{tmp}/ok.rrd", "--mp4", "{tmp}/ok.mp4", "--json", "{tmp}/d.json"], "is a folder",
        files={"d.json/keep": ""}),
    "run --rrd a folder": Case(["run", *ORACLE, "--rrd", "{tmp}/adir.rrd"], "is a folder", files={"adir.rrd/keep": ""}),
    "run --rrd without its suffix": Case(["run", *ORACLE, "--rrd", "{tmp}/out.txt"], "ending in .rrd"),
    "run --mcap-images without --mcap": Case(["run", *ORACLE, "--mcap-images", "jpeg"], "add --mcap FILE"),
    "run --rrd in /proc": Case(["run", *ORACLE, "--rrd", "/proc/x.rrd"], "cannot write in /proc"),
    "run --mp4 in /proc": Case(["run", *ORACLE, "--mp4", "/proc/x.mp4"], "cannot write in /proc"),
    "run --mp4 not .mp4": Case(["run", *ORACLE, "--mp4", "{tmp}/x.avi"], ".mp4"),
    "snapshot --out in /proc": Case(["snapshot", "--out", "/proc/snapx"], "cannot write in /proc"),
    "snapshot --out under a file": Case(["snapshot", "--out", "{tmp}/afile/snap"], "is a file", files={"afile": "x"}),
    "snapshot --out ''": Case(["snapshot", "--out", ""], "prefix"),
    "sweep --out a file": Case(["sweep", str(SMOKE), "--out", "{tmp}/afile"], "not a folder", files={"afile": "x"}),
    "realism --out holding a run": Case(["realism", "--towns", "town07", "--out", "{tmp}/r"], "already holds report.md, frames.jsonl",
                                        files={"r/frames.jsonl": "{}\n", "r/report.md": "# the first run"}),
    "realism --out holding a report of the user's": Case(["realism", "--towns", "town07", "--out", "{tmp}/r"],
                                                         "already holds report.md", files={"r/report.md": "mine"}),
    "sweep a folder": Case(["sweep", "{tmp}/sweeps", "--out", "{tmp}/out"], "sweeps is a folder; give the sweep file",
                           files={"sweeps/keep": ""}),
    "sweep --out in /proc": Case(["sweep", str(SMOKE), "--out", "/proc/sweep"], "cannot write in /proc"),
    "reproduce --out a file": Case(["reproduce", "--out", "{tmp}/afile"], "not a folder", files={"afile": "x"}),
    "reproduce --out in /sys": Case(["reproduce", "--out", "/sys/results"], "cannot write in /sys"),
    "attack generate --out not .png": Case(["attack", "generate", "--method", "yang", "--out", "{tmp}/t.txt"], ".png"),
    "attack generate --out a folder": Case(["attack", "generate", "--method", "yang", "--out", "{tmp}/d.png"],
                                           "is a folder", files={"d.png/keep": ""}),
    "attack eval --out a file": Case(["attack", "eval", "--out", "{tmp}/afile"], "not a folder", files={"afile": "x"}),
    "attack eval: a second detector with no drive-bys": Case(
        ["attack", "eval", "--drives", "0", "--detectors", "detector,coco", "--signs", "clean", "--out", "{tmp}/ae"],
        "--drives 0 runs none"),
    "attack eval: one texture by two names": Case(
        ["attack", "eval", "--drives", "0", "--signs", "clean,stop_sign", "--out", "{tmp}/ae"], "one texture twice"),
    "attack sweep --out in /proc": Case(["attack", "sweep", "--method", "yang", "--budgets", "0.1", "--out", "/proc/a"],
                                        "cannot write in /proc"),
    "attack sweep --closed-loop: no such file": Case(
        ["attack", "sweep", "--method", "yang", "--budgets", "0.1", "--closed-loop", "{tmp}/none.toml", "--out", "{tmp}/out"],
        "none.toml"),
    "attack sweep --closed-loop: no clean cell": Case(
        ["attack", "sweep", "--method", "yang", "--budgets", "0.1", "--closed-loop", "{tmp}/p.toml", "--out", "{tmp}/out"],
        'no cell named "clean"',
        files={"p.toml": 'title = "t"\nseeds = 2\n[[cells]]\nname = "attacked"\nscenario = { sign = "yang" }\n'}),
    "detector make-data --out a file": Case(["detector", "make-data", "--out", "{tmp}/afile"], "not a folder",
                                            files={"afile": "x"}),
    "detector train --out a folder": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/adir"], "is a folder",
                                          files={"adir/keep": ""}),
    "detector export --out in /proc": Case(["detector", "export", "--checkpoint", "c.pt", "--out", "/proc/w.pt"],
                                           "cannot write in /proc"),
    "detector eval --out a file": Case(["detector", "eval", "--out", "{tmp}/afile"], "not a folder", files={"afile": "x"}),
    "detector eval --data a file": Case(["detector", "eval", "--data", "{tmp}/afile", "--out", "{tmp}/ev"],
                                        "afile is a file; a detector dataset is a folder", files={"afile": "x"}),
    "detector train --data a file": Case(["detector", "train", "--data", "{tmp}/afile", "--out", "{tmp}/c.pt"],
                                         "afile is a file; a detector dataset is a folder", files={"afile": "x"}),
    "detector export --format onnx --out .pt": Case(["detector", "export", "--format", "onnx", "--out", "{tmp}/w.pt"],
                                                    "--out (--format onnx) expects a path ending in .onnx"),
    "detector export --format pt --out .onnx": Case(["detector", "export", "--checkpoint", "c.pt", "--out", "{tmp}/w.onnx"],
                                                    "add --format onnx"),
    # ---- values refused up front ----------------------------------------------------------------------------
    "bench --profile --recording": Case(["bench", "--profile", "--recording"], "not allowed with"),
    "snapshot --dist-m nan": Case(["snapshot", "--dist-m", "nan", "--out", "{tmp}/s"], "--dist-m"),
    "snapshot --dist-m 1e9": Case(["snapshot", "--dist-m", "1e9", "--out", "{tmp}/s"], "--dist-m"),
    "--physics-dt-s 1e-300": Case(["run", *ORACLE, "--physics-dt-s", "1e-300"], "--physics-dt-s: must be in [0.0001, 0.01] s"),
    "seed 2**64": Case(["run", *ORACLE, "--set", f"scenario.seed={2**64}"], "scenario.seed"),
    "seed 1e23": Case(["run", *ORACLE, "--set", "scenario.seed=100000000000000000000000"], str(MAX_SEED)),
    "--seed past 2**32 - 1": Case(["run", *ORACLE, "--seed", str(MAX_SEED + 1)], str(MAX_SEED)),
    "attack --seed negative": Case(["attack", "generate", "--method", "yang", "--seed", "-1", "--out", "{tmp}/t.png"], "--seed"),
    "policy.a_max_mps2": Case(["run", *ORACLE, "--set", "policy.a_max_mps2=1e6"], "policy.a_max_mps2"),
    "policy.sign_height_m": Case(["run", *ORACLE, "--set", "policy.sign_height_m=100"], "policy.sign_height_m"),
    "policy.stop_line_before_sign_m": Case(["run", *ORACLE, "--set", "policy.stop_line_before_sign_m=-5"],
                                           "policy.stop_line_before_sign_m"),
    "policy.autopilot_decel_fraction": Case(["run", *ORACLE, "--set", "policy.autopilot_decel_fraction=1e6"],
                                            "policy.autopilot_decel_fraction"),
    "policy.trigger_dist_m": Case(["run", *ORACLE, "--set", "policy.trigger_dist_m=-5"], "policy.trigger_dist_m"),
    "policy.study_sign_height_m": Case(["run", *ORACLE, "--set", "policy.study_sign_height_m=100"],
                                       "policy.study_sign_height_m"),
    "scenario.road_friction": Case(["run", *ORACLE, "--set", "scenario.road_friction=7"], "scenario.road_friction"),
    # ---- files that are not what they claim -------------------------------------------------------------------
    "sweep: a binary TOML": Case(["sweep", "{tmp}/bin.toml", "--out", "{tmp}/out"], "not a text TOML",
                                 files={"bin.toml": b"\x80\x81\xfe\x00binary"}),
    "run --config: a binary TOML": Case(["run", "--config", "{tmp}/bin.toml"], "not a text TOML",
                                        files={"bin.toml": b"\x80\x81\xfe\x00binary"}),
    "sweep grid: a texture that is not a PNG": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "not a PNG",
        files={"s.toml": SWEEP + "'scenario.sign' = ['clean', '{tmp}/fake.png']\n", "fake.png": "not a png"}),
    "sweep grid: clean and stop_sign": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "same texture",
        files={"s.toml": SWEEP + "'scenario.sign' = ['clean', 'stop_sign']\n"}),
    "sweep --resume: a corrupt line in the middle": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "line 2 is corrupt",
        files={"out/results.jsonl": _record(0) + "garbage\n" + _record(1)}),
    "sweep --resume: a [1,2] line": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "line 2 is corrupt",
        files={"out/results.jsonl": _record(0) + "[1,2]\n" + _record(1)}),
    "sweep --resume: a foreign file": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "not an avsim results file",
        files={"out/results.jsonl": '{"name": "someone else"}\n{"name": "theirs"}\n'}),
    "sweep --resume: a binary file": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "not an avsim results file",
        files={"out/results.jsonl": b"\xff\xfe\x00\x01\n"}),
    "detector eval without data": Case(["detector", "eval", "--data", "{tmp}/data/signs", "--out", "{tmp}/ev"],
                                       "avsim detector make-data --out"),
    # ---- the environment --------------------------------------------------------------------------------------
    "MUJOCO_GL=nonsense": Case(["run", *ORACLE], "egl", env={"MUJOCO_GL": "nonsense"}),
    "MUJOCO_GL=glfw (needs a display)": Case(["run", *ORACLE], "osmesa", env={"MUJOCO_GL": "glfw"}),
    # ---- argparse's own checks ----------------------------------------------------------------------------------
    "--seed 1e23": Case(["run", "--seed", "1e23"], "expects an integer"),
    "an unknown flag": Case(["snapshot", "--perception", "oracle"], "unrecognized arguments"),
}


@pytest.fixture
def no_simulation(monkeypatch):
    """Fail the test if a closed loop (the simulator) is even built."""

    def _boom(self, *args, **kwargs):
        raise AssertionError("the CLI built the simulator before rejecting bad input")

    monkeypatch.setattr(avsim.loop.ClosedLoop, "__init__", _boom)


def _files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.mark.parametrize("case", list(CASES.values()), ids=list(CASES))
def test_bad_input_is_one_line_and_writes_nothing(case, tmp_path, capsys, monkeypatch, no_simulation):
    tmp = str(tmp_path)
    write_files(tmp_path, case.files, tmp)
    for key, value in case.env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.chdir(tmp_path)  # relative default outputs (results/, snapshot_*.png) land here too
    before = _files_under(tmp_path)

    argv = [arg.replace("{tmp}", tmp) for arg in case.argv]
    try:
        status = cli.main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    captured = capsys.readouterr()

    lines = captured.err.splitlines()
    assert status == case.status, captured.err
    assert len(lines) == 1, captured.err
    assert case.mention in captured.err, captured.err
    assert "Traceback" not in captured.err
    assert captured.out == ""
    assert _files_under(tmp_path) == before  # no output file, no temporary file, no folder


def test_a_read_only_folder_is_refused(tmp_path, capsys, no_simulation):
    if os.geteuid() == 0:
        pytest.skip("root writes into a read-only folder; /proc and /sys stand in for it in the table above")
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert cli.main(["run", *ORACLE, "--json", str(folder / "x.json")]) == 2
    finally:
        folder.chmod(0o755)
    assert "cannot write in" in capsys.readouterr().err
    assert list(folder.iterdir()) == []


def test_osmesa_without_its_library_names_the_package(monkeypatch, capsys, no_simulation):
    import avsim.sensors.gl_backend as gl_backend

    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)  # set to egl when this process imported MuJoCo
    monkeypatch.setattr(gl_backend, "library_loads", lambda name: name != "OSMesa")
    assert cli.main(["run", *ORACLE]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "apt-get install libosmesa6" in lines[0]


def test_every_output_argument_of_every_subcommand_is_declared_and_so_checked():
    """A new subcommand's --out/--json/... must be declared with add_output_argument, so that
    `main` checks it before any work (this walks every parser, new ones included)."""
    from avsim.outputs import declared_outputs

    output_like = {"out", "json", "rrd", "mp4", "mcap", "output"}
    for name, parser in command.iter_parsers(command.build_parser()):
        declared = {spec.dest for spec in declared_outputs(parser)}
        for action in parser._actions:
            if action.dest in output_like:
                assert action.dest in declared, f"`{name} {action.option_strings[0]}` is not declared as an output"


# ---- the error boundary ----------------------------------------------------------------------------------------

def _patched_command(monkeypatch, error: BaseException) -> None:
    def _raise(args):
        raise error

    monkeypatch.setattr(cli.bench, "_cmd_bench", _raise)


def test_a_bug_is_one_line_with_the_path_of_its_full_traceback(monkeypatch, capsys):
    _patched_command(monkeypatch, ValueError("something inside\nwith a second line"))
    assert cli.main(["bench"]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("avsim: internal error: ValueError: something inside")
    where = lines[0].split("full traceback in ")[1].split(",")[0]
    text = Path(where).read_text()
    Path(where).unlink()
    assert "Traceback" in text and "ValueError: something inside" in text


def test_an_os_error_names_its_file_and_is_not_called_a_bug(monkeypatch, capsys):
    _patched_command(monkeypatch, OSError(28, "No space left on device", "/data/out.csv"))
    assert cli.main(["bench"]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("avsim: error: No space left on device: '/data/out.csv'")
    Path(lines[0].split("full traceback in ")[1].split(",")[0]).unlink()


def test_debug_prints_the_full_traceback(monkeypatch, capsys):
    _patched_command(monkeypatch, ValueError("boom"))
    assert cli.main(["bench", "--debug"]) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and err.splitlines()[-1].startswith("avsim: internal error")
    Path(err.split("full traceback in ")[1].split(",")[0]).unlink()


def test_ctrl_c_is_one_line_and_exit_130(monkeypatch, capsys):
    _patched_command(monkeypatch, KeyboardInterrupt())
    assert cli.main(["bench"]) == 130
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("avsim: interrupted")


def test_a_physics_error_keeps_its_own_status(monkeypatch, capsys):
    from avsim.errors import PhysicsError

    _patched_command(monkeypatch, PhysicsError("physics diverged at t = 1.00 s"))
    assert cli.main(["bench"]) == 3
    assert capsys.readouterr().err == "avsim: error: physics diverged at t = 1.00 s\n"


@pytest.mark.parametrize("argv", [["--help"], ["run", "--perception", "oracle"]])
def test_an_unknown_mujoco_gl_is_refused_before_mujoco_is_imported(argv):
    # In a fresh process: this one imported MuJoCo long ago, under MUJOCO_GL=egl, so only a new
    # interpreter shows what importing the command modules does with a bad value (a traceback, once).
    env = {**os.environ, "MUJOCO_GL": "bogus"}
    env.pop("PYOPENGL_PLATFORM", None)
    done = subprocess.run([sys.executable, "-m", "avsim", *argv], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == ["avsim: error: MUJOCO_GL='bogus' is not an offscreen renderer avsim can use; "
                                        "set MUJOCO_GL to one of: egl (Debian package libegl1), osmesa (Debian package libosmesa6)"]
    assert done.stdout == ""


def test_importing_the_command_line_package_does_not_import_mujoco():
    probe = "import sys, avsim.cli; print('mujoco' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.stdout.strip() == "False", done.stderr
