"""Issue 26, by class: bad input that used to reach an internal error, meaningless runs that used
to be accepted, and checks that came too late. Every case is refused before any work: exit 2, at
most two lines on stderr, nothing on stdout, and no file or folder left behind.

The cases differ from the ones the issue lists (those are the classes' known members; these
check that the mechanism, not a patch, covers the class). `no_simulation` fails the test if a
closed loop is even built, and `no_view_bank` if an attack renders its view bank.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import avsim.attacks.view_bank
import avsim.loop
from avsim import cli
from avsim.sensors.gl import GLInfo
from helpers import write_files

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "experiments" / "sweeps" / "sweep_smoke.toml"
ORACLE = ["--perception", "oracle"]


def _png_header(width: int, height: int) -> bytes:
    """A PNG whose header declares width x height pixels, with almost no data (a decompression bomb)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def _noise_png(width: int, height: int) -> bytes:
    """A whole PNG of random pixels (so that half of it leaves its image data cut short)."""
    import cv2
    import numpy as np

    pixels = np.random.default_rng(0).integers(0, 255, (height, width, 3), dtype=np.uint8)
    return cv2.imencode(".png", pixels)[1].tobytes()


def _gif_header(width: int, height: int) -> bytes:
    return b"GIF89a" + struct.pack("<HH", width, height) + b"\x00\x00\x00;"


def _record(seed: int, **result: object) -> str:
    """A results.jsonl line of the smoke sweep's kind, with `result` fields laid over an ok result."""
    base = {"outcome": "stopped_before_line", "margin_m": 3.0, "sign_margin_m": 4.0, "dist_at_brake_m": 30.0,
            "stop_position_m": [-3.0, -1.7], "sign_position_m": [1.0, -5.5], "time_to_stop_s": 2.0}
    line = {"experiment": "sweep_smoke", "cell": "x", "seed": seed, "spec_hash": f"h{seed}", "status": "ok",
            "error": None, "result": {**base, **result}, "trace": None, "rrd": None, "wall_s": 1.0}
    return json.dumps(line) + "\n"


@dataclass(frozen=True)
class Case:
    """argv with {tmp} for the test's folder; mention: words the refusal must contain.

    files: {relative path: text or bytes} made before the case runs (they may stay, nothing else may appear).
    """

    argv: list[str]
    mention: str
    files: dict[str, str | bytes] = field(default_factory=dict)


SWEEP_HEAD = 'title = "t"\n[defaults]\nperception = { kind = "oracle" }\n[grid]\n'

# ---- internal errors from bad input: each reached a Python exception deep in the work --------------
INTERNAL = {
    "snapshot --towns ' , '": Case(["snapshot", "--towns", " , ", "--strip", "--out", "{tmp}/s"], "--towns"),
    "snapshot --towns town07,,town03": Case(["snapshot", "--towns", "town07,,town03", "--strip", "--out", "{tmp}/s"],
                                            "empty name"),
    "detect: a GIF declaring 60000x60000": Case(["detect", "{tmp}/big.gif"], "megapixels",
                                                files={"big.gif": _gif_header(60000, 60000)}),
    "detect: a PNG declaring 8000x8000": Case(["detect", "{tmp}/b.png"], "megapixels", files={"b.png": _png_header(8000, 8000)}),
    "detector train --epochs 0": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt", "--epochs", "0"],
                                      "--epochs"),
    "detector train --batch-size -4": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt",
                                            "--batch-size", "-4"], "--batch-size"),
    "detector train --lr inf": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt", "--lr", "inf"], "--lr"),
    "detector train --width-mult -1": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt",
                                            "--width-mult", "-1"], "--width-mult"),
    "detector train --device tpu": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt", "--device", "tpu"],
                                        "--device"),
    "detector train --device cuda:3": Case(["detector", "train", "--data", "{tmp}", "--out", "{tmp}/w.pt",
                                            "--device", "cuda:3"], "cuda"),
    "detector eval: a binary val.jsonl": Case(["detector", "eval", "--data", "{tmp}/d", "--out", "{tmp}/ev"], "not UTF-8",
                                              files={"d/val.jsonl": b"\xff\xfe\x00\x01binary\n"}),
    "detector eval: a label line without boxes": Case(["detector", "eval", "--data", "{tmp}/d", "--out", "{tmp}/ev"],
                                                      "val.jsonl:1", files={"d/val.jsonl": '{"image": "a.png"}\n'}),
    "attack generate --from: a record with a NaN seed": Case(
        ["attack", "generate", "--from", "{tmp}/r.json", "--out", "{tmp}/t.png"], "finite",
        files={"r.json": '{"method": "yang", "seed": NaN, "hyperparameters": {}, "view_bank": {}, "weights_sha256": {}}'}),
    "attack generate --from: a UTF-16 record": Case(["attack", "generate", "--from", "{tmp}/r.json", "--out", "{tmp}/t.png"],
                                                    "UTF-8", files={"r.json": '{"method": "yang"}'.encode("utf-16")}),
    "attack generate --set eps=inf": Case(["attack", "generate", "--method", "chen", "--set", "eps=inf",
                                           "--out", "{tmp}/t.png"], "eps"),
    "attack generate --set lr=fast": Case(["attack", "generate", "--method", "lu_v2", "--set", "lr=fast",
                                           "--out", "{tmp}/t.png"], "lr"),
    "attack generate --set n_stickers=2.5": Case(["attack", "generate", "--method", "eykholt", "--set", "n_stickers=2.5",
                                                  "--out", "{tmp}/t.png"], "an integer"),
    "attack sweep --budgets 0.1,,0.2": Case(["attack", "sweep", "--method", "yang", "--budgets", "0.1,,0.2",
                                             "--out", "{tmp}/o"], "--budgets"),
    "attack sweep --workers 0": Case(["attack", "sweep", "--method", "yang", "--budgets", "0.1", "--workers", "0",
                                      "--out", "{tmp}/o"], "must be an integer in [1, 64]"),
    "attack sweep --budgets inf": Case(["attack", "sweep", "--method", "chen", "--budgets", "inf", "--out", "{tmp}/o"],
                                       "--budgets"),
    "sweep: 20 values x 1000 seeds without --yes": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "--yes",
        files={"s.toml": "seeds = 1000\n" + SWEEP_HEAD + '"scenario.speed_kmh" = [' + ", ".join(str(v) for v in range(10, 30)) + "]\n"}),
    "sweep: more runs than any command runs": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out", "--yes"], "split it",
        files={"s.toml": "seeds = 900000\n" + SWEEP_HEAD + '"scenario.speed_kmh" = [30, 60]\n'}),
    "sweep --resume: a string where a number belongs": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "line 2",
        files={"out/results.jsonl": _record(0) + _record(1, margin_m="far")}),
    "sweep --resume: an infinite distance": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "line 1",
        files={"out/results.jsonl": _record(0, sign_margin_m=float("inf")) + _record(1)}),
    "sweep --resume: a negative time to stop": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "time_to_stop_s",
        files={"out/results.jsonl": _record(0) + _record(1, time_to_stop_s=-2.0)}),
    "sweep --resume: a brake command above full": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "max_brake",
        files={"out/results.jsonl": _record(0, max_brake=1.5)}),
    "replay: an .mcap cut after its magic": Case(["replay", "{tmp}/b.mcap"], "cut short", files={"b.mcap": b"\x89MCAP0\r\n"}),
    "replay: a folder that is no bag": Case(["replay", "{tmp}/notabag"], "metadata.yaml", files={"notabag/keep": ""}),
    "sweep --resume: a seed that is text": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--resume"], "seed",
        files={"out/results.jsonl": _record(0) + _record(1).replace('"seed": 1', '"seed": "1"')}),
}

# ---- meaningless runs that were accepted in silence -----------------------------------------------
MEANINGLESS = {
    "run: at rest 35 m out, inside the 40 m gate": Case(["run", *ORACLE, "--set", "scenario.start_dist_m=35"],
                                                        "braking gate"),
    "run: adjusted braking with a 100 m gate, from rest at 90 m": Case(
        ["run", *ORACLE, "--policy", "adjusted", "--set", "policy.trigger_dist_m=100", "--set", "scenario.start_dist_m=90"],
        "braking gate"),
    "run: side_camera with perception none": Case(["run", "--policy", "side_camera", "--perception", "none"], "blind"),
    "sweep: a grid point with a perceiving policy and no perception": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "blind",
        files={"s.toml": 'title = "t"\n[defaults]\nperception = { kind = "none" }\n[grid]\n"policy.name" = ["autopilot", "temporal_vote"]\n'}),
    "run: --json and --mp4 on one file": Case(["run", *ORACLE, "--json", "{tmp}/x.mp4", "--mp4", "{tmp}/x.mp4"], "both write"),
    "run: --json onto its own --config": Case(["run", "--config", "{tmp}/e.toml", "--json", "{tmp}/e.toml"], "--config reads",
                                              files={"e.toml": 'title = "t"\n[[cells]]\nname = "a"\n'}),
    "run: --rrd onto its --sign texture": Case(["run", *ORACLE, "--sign", "{tmp}/s.rrd", "--rrd", "{tmp}/./s.rrd"],
                                               "--sign reads", files={"s.rrd": _png_header(64, 64)}),
    "attack generate: its record beside --out is the --from record": Case(
        ["attack", "generate", "--from", "{tmp}/t.json", "--out", "{tmp}/t.png"], "--from reads", files={"t.json": "{}"}),
    "replay --out onto its bag": Case(["replay", "{tmp}/b.mcap", "--out", "{tmp}/b.mcap"], "the bag argument reads",
                                      files={"b.mcap": b"\x89MCAP0\r\n"}),
    "run: --rrd and --json through a ./ path": Case(["run", *ORACLE, "--rrd", "{tmp}/a.rrd", "--json", "{tmp}/./a.rrd"],
                                                    "both write"),
    "detector eval: a split that lists no image": Case(["detector", "eval", "--data", "{tmp}/d", "--out", "{tmp}/ev"],
                                                       "lists no images", files={"d/val.jsonl": "\n"}),
    "detector eval --conf 0": Case(["detector", "eval", "--conf", "0", "--out", "{tmp}/ev"], "--conf"),
    "detector eval --conf -inf": Case(["detector", "eval", "--conf=-inf", "--out", "{tmp}/ev"], "--conf"),
    "attack generate --set eps=0": Case(["attack", "generate", "--method", "lu_v3", "--set", "eps=0", "--out", "{tmp}/t.png"],
                                        "eps"),
    "attack generate --set max_area_fraction=1.5": Case(["attack", "generate", "--method", "eykholt", "--set",
                                                         "max_area_fraction=1.5", "--out", "{tmp}/t.png"], "max_area_fraction"),
    "attack sweep --budgets 0.1,-0.2": Case(["attack", "sweep", "--method", "yang", "--budgets", "0.1,-0.2",
                                             "--out", "{tmp}/o"], "--budgets"),
}

# ---- checks that came after the work ------------------------------------------------------------
LATE = {
    "attack generate --steps -3": Case(["attack", "generate", "--method", "yang", "--steps", "-3", "--out", "{tmp}/t.png"],
                                       "--steps"),
    "attack generate --views-per-step 0": Case(["attack", "generate", "--method", "chen", "--views-per-step", "0",
                                                "--out", "{tmp}/t.png"], "--views-per-step"),
    "attack generate --set saliency_views=nan": Case(["attack", "generate", "--method", "yang", "--set",
                                                      "saliency_views=nan", "--out", "{tmp}/t.png"], "saliency_views"),
    "attack sweep --steps 0": Case(["attack", "sweep", "--method", "chen", "--budgets", "0.1", "--steps", "0",
                                    "--out", "{tmp}/o"], "--steps"),
    "attack eval --placements near,diagonal": Case(["attack", "eval", "--placements", "near,diagonal", "--out", "{tmp}/ae"],
                                                   "diagonal"),
    "attack eval --town town99": Case(["attack", "eval", "--town", "town99", "--out", "{tmp}/ae"], "town99"),
    "attack eval --setting glossy": Case(["attack", "eval", "--setting", "glossy", "--out", "{tmp}/ae"], "glossy"),
    "attack eval --set a key it sets itself": Case(["attack", "eval", "--set", "perception.kind=coco", "--out",
                                                     "{tmp}/ae"], "attack eval sets it itself; choose"),
    "attack eval --set a key it does not read": Case(["attack", "eval", "--set", "vehicle.mass_kg=900", "--out",
                                                      "{tmp}/ae"], "reads camera, scenario and perception keys"),
    "attack eval --set a key the setting sets": Case(["attack", "eval", "--setting", "textured", "--set",
                                                      "scenario.materials=flat", "--out", "{tmp}/ae"],
                                                     "--setting textured sets it too"),
    "attack eval --set a bad value": Case(["attack", "eval", "--set", "scenario.fog_end_m=-3", "--out", "{tmp}/ae"],
                                          "fog_end_m"),
    "attack eval --weights corrupt": Case(["attack", "eval", "--weights", "{tmp}/w.pt", "--out", "{tmp}/ae"], "w.pt",
                                          files={"w.pt": b"not a checkpoint"}),
    "attack eval --weights without the detector": Case(["attack", "eval", "--detectors", "coco", "--weights",
                                                        "{tmp}/w.pt", "--out", "{tmp}/ae"], "--detectors",
                                                       files={"w.pt": b"not a checkpoint"}),
    "run --sign a folder": Case(["run", *ORACLE, "--sign", "{tmp}/signs/"], "is a folder", files={"signs/keep": ""}),
    "detect a folder": Case(["detect", "{tmp}/imgs"], "is a folder", files={"imgs/keep": ""}),
    # Before: the first image's line was printed, then the second stopped the command.
    "detect: a whole image, then one cut short": Case(["detect", "{tmp}/whole.png", "{tmp}/cut.png"], "cut.png",
                                                      files={"whole.png": _noise_png(64, 48),
                                                             "cut.png": _noise_png(64, 48)[:4000]}),
    "detector eval --limit -1": Case(["detector", "eval", "--limit", "-1", "--out", "{tmp}/ev"], "--limit"),
    "make-data --images-per-scene 0": Case(["detector", "make-data", "--images-per-scene", "0", "--out", "{tmp}/d"],
                                           "images_per_scene"),
}


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a closed loop or an attack's view bank is even built."""

    def _boom(*args, **kwargs):
        raise AssertionError("the command started its work before refusing bad input")

    monkeypatch.setattr(avsim.loop.ClosedLoop, "__init__", _boom)
    monkeypatch.setattr(avsim.attacks.view_bank, "build_view_bank", _boom)


def _files_under(root: Path) -> dict[str, bytes | None]:
    """Every path under `root` with its bytes (None for a folder): a refusal leaves each as it was."""
    return {str(p.relative_to(root)): p.read_bytes() if p.is_file() else None for p in root.rglob("*")}


def _run_case(case: Case, tmp_path: Path, capsys, monkeypatch) -> None:
    tmp = str(tmp_path)
    write_files(tmp_path, case.files, tmp)
    monkeypatch.chdir(tmp_path)  # relative default outputs (results/, data/signs) land here too
    before = _files_under(tmp_path)
    status = cli.main([arg.replace("{tmp}", tmp) for arg in case.argv])
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert status == 2, captured.err
    assert 1 <= len(lines) <= 2, captured.err
    assert case.mention in captured.err, captured.err
    assert "internal error" not in captured.err and "Traceback" not in captured.err
    assert captured.out == ""
    assert _files_under(tmp_path) == before  # no output file, no temporary file, no folder, no input replaced


@pytest.mark.parametrize("case", list(INTERNAL.values()), ids=list(INTERNAL))
def test_bad_input_that_reached_an_internal_error_is_one_line(case, tmp_path, capsys, monkeypatch, no_work):
    _run_case(case, tmp_path, capsys, monkeypatch)


@pytest.mark.parametrize("case", list(MEANINGLESS.values()), ids=list(MEANINGLESS))
def test_a_run_that_cannot_mean_what_it_says_is_refused(case, tmp_path, capsys, monkeypatch, no_work):
    _run_case(case, tmp_path, capsys, monkeypatch)


@pytest.mark.parametrize("case", list(LATE.values()), ids=list(LATE))
def test_values_are_checked_before_the_work_not_after(case, tmp_path, capsys, monkeypatch, no_work):
    _run_case(case, tmp_path, capsys, monkeypatch)


# ---- python -m entry points share the layer and the boundary ----------------------------------------

ENTRY_POINTS = {
    "brake_test --speed-kmh inf": ("avsim.vehicle.brake_test", ["--speed-kmh", "inf"], "--speed-kmh"),
    "brake_test --speed-kmh 0": ("avsim.vehicle.brake_test", ["--speed-kmh", "0"], "--speed-kmh"),
    "bench_sweep --seeds 0": ("avsim.bench.sweep_throughput", ["--seeds", "0"], "--seeds"),
    "bench_latency --threads 0": ("avsim.bench.detector_latency", ["--threads", "0"], "--threads"),
    "detector.train --lr nan": ("avsim.perception.detector.train", ["--data", "d", "--out", "w.pt", "--lr", "nan"], "--lr"),
    "coco.realism --threshold 1": ("avsim.perception.coco.realism", ["--data", "d", "--threshold", "1"], "--threshold"),
    "world.textures --out x (it takes no arguments)": ("avsim.world.textures", ["--out", "x"], "unrecognized arguments"),
    "coco.fetch --bogus (it takes no arguments)": ("avsim.perception.coco.fetch", ["--bogus"], "unrecognized arguments"),
    "nanodet.fetch x (it takes no arguments)": ("avsim.perception.nanodet.fetch", ["x"], "unrecognized arguments"),
    "precision_agreement --conf x": ("avsim.perception.detector.precision_agreement", ["--conf", "x"], "--conf"),
    "precision_agreement on a folder without labels": ("avsim.perception.detector.precision_agreement", ["--data", "/dev"],
                                                        "val.jsonl is missing"),
}


@pytest.mark.parametrize("module, argv, mention", list(ENTRY_POINTS.values()), ids=list(ENTRY_POINTS))
def test_module_entry_points_refuse_bad_numbers_in_one_line(module, argv, mention, tmp_path, capsys, monkeypatch):
    import importlib

    monkeypatch.chdir(tmp_path)
    main = importlib.import_module(module).main
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's refusal
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and 1 <= len(err.splitlines()) <= 2 and mention in err, err
    assert list(tmp_path.iterdir()) == []


# ---- a network arithmetic this CPU cannot run ------------------------------------------------------

BF16_ON_A_CPU_WITHOUT_IT = {
    "run --set perception.coco_precision=bf16": Case(
        ["run", "--perception", "coco", "--set", "perception.coco_precision=bf16"], "set perception.coco_precision=auto or fp32"),
    "reproduce: an experiment file's yolo_precision = bf16": Case(
        ["reproduce", "--experiments", "{tmp}/e.toml", "--out", "{tmp}/out"], "set perception.yolo_precision=auto or fp32",
        files={"e.toml": 'seeds = 1\n[defaults]\nperception = { kind = "yolo", yolo_precision = "bf16" }\n'
                         '[[cells]]\nname = "a"\n'}),
    "sweep: a grid point's detector_precision = bf16": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "set perception.detector_precision=auto or fp32",
        files={"s.toml": 'seeds = 1\n[defaults]\nperception = { kind = "detector" }\n'
                         '[grid]\n"perception.detector_precision" = ["fp32", "bf16"]\n'}),
}


@pytest.mark.parametrize("case", list(BF16_ON_A_CPU_WITHOUT_IT.values()), ids=list(BF16_ON_A_CPU_WITHOUT_IT))
def test_bf16_on_a_cpu_without_its_kernels_is_refused_before_the_first_run(case, tmp_path, capsys, monkeypatch, no_work):
    # "auto" runs fp32 on such a CPU (an AVX2 one); an explicit "bf16" would run through slow reference code.
    monkeypatch.setattr("torch.ops.mkldnn._is_mkldnn_bf16_supported", lambda: False)
    _run_case(case, tmp_path, capsys, monkeypatch)


# ---- no offscreen rendering, or weights that do not load, named by a batch file -------------------------

NO_OFFSCREEN_RENDERING = {
    "sweep": Case(["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "cannot start offscreen rendering",
                  files={"s.toml": 'seeds = 1\n[grid]\n"policy.name" = ["baseline", "adjusted"]\n'}),
    "reproduce": Case(["reproduce", "--experiments", "{tmp}/e.toml", "--out", "{tmp}/out"], "cannot start offscreen rendering",
                      files={"e.toml": 'seeds = 1\n[[cells]]\nname = "a"\n'}),
    "leaderboard --quick": Case(["leaderboard", "--quick", "--out", "{tmp}/out"], "cannot start offscreen rendering"),
    "detector make-data": Case(["detector", "make-data", "--train", "2", "--val", "2", "--out", "{tmp}/data"],
                               "cannot start offscreen rendering"),
}


@pytest.mark.parametrize("case", list(NO_OFFSCREEN_RENDERING.values()), ids=list(NO_OFFSCREEN_RENDERING))
def test_a_machine_that_cannot_render_is_refused_before_a_batch_starts(case, tmp_path, capsys, monkeypatch, no_work):
    # Before: every run of the batch failed in its worker, and a results folder of failures was left.
    def no_egl(*args, **kwargs):
        raise RuntimeError("Cannot initialize a EGL device display")

    monkeypatch.setattr("avsim.sensors.gl.mujoco.GLContext", no_egl)
    _run_case(case, tmp_path, capsys, monkeypatch)


# ---- more texture anisotropy than this GL filters ---------------------------------------------------

MORE_ANISOTROPY_THAN_THE_GL_OFFERS = {
    "run --set camera.texture_anisotropy=16": Case(["run", "--set", "camera.texture_anisotropy=16"], "filters at most 8:1"),
    "reproduce --setting textured_aniso16": Case(
        ["reproduce", "--experiments", "{tmp}/e.toml", "--setting", "textured_aniso16", "--out", "{tmp}/out"],
        "filters at most 8:1", files={"e.toml": 'seeds = 1\n[[cells]]\nname = "a"\n'}),
    "sweep: one grid point's anisotropy": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "set camera.texture_anisotropy to 1",
        files={"s.toml": 'seeds = 1\n[grid]\n"camera.texture_anisotropy" = [1, 16]\n'}),
    "leaderboard --quick --setting textured_aniso16": Case(
        ["leaderboard", "--quick", "--setting", "textured_aniso16", "--out", "{tmp}/out"], "filters at most 8:1"),
    "realism --settings textured,textured_aniso16": Case(
        ["realism", "--settings", "textured,textured_aniso16", "--towns", "town07", "--frames", "1", "--out", "{tmp}/r"],
        "filters at most 8:1"),
}


@pytest.mark.parametrize("case", list(MORE_ANISOTROPY_THAN_THE_GL_OFFERS.values()), ids=list(MORE_ANISOTROPY_THAN_THE_GL_OFFERS))
def test_more_anisotropy_than_the_gl_offers_is_refused_before_the_first_run(case, tmp_path, capsys, monkeypatch, no_work):
    # Before: the batch started, and each run's renderer refused when it was built.
    monkeypatch.setattr("avsim.sensors.gl._gl_info", lambda: GLInfo("a GL of 8:1", "4.6", 8.0))
    _run_case(case, tmp_path, capsys, monkeypatch)


_CORRUPT_WEIGHTS = b"not a torch file" * 64
BAD_WEIGHTS_IN_A_BATCH_FILE = {
    "sweep: corrupt weights in [defaults]": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "are corrupt",
        files={"w.pt": _CORRUPT_WEIGHTS, "s.toml": 'seeds = 1\n[defaults]\nperception = { weights_path = "{tmp}/w.pt" }\n'
                                                   '[grid]\n"policy.name" = ["baseline", "adjusted"]\n'}),
    "sweep: missing weights on one grid point": Case(
        ["sweep", "{tmp}/s.toml", "--out", "{tmp}/out"], "missing",
        files={"s.toml": 'seeds = 1\n[grid]\n"perception.weights_path" = ["", "{tmp}/none.pt"]\n'}),
    "reproduce: corrupt weights in a cell": Case(
        ["reproduce", "--experiments", "{tmp}/e.toml", "--out", "{tmp}/out"], "are corrupt",
        files={"w.pt": _CORRUPT_WEIGHTS, "e.toml": 'seeds = 1\n[[cells]]\nname = "a"\n'
                                                   '[[cells]]\nname = "b"\nperception = { weights_path = "{tmp}/w.pt" }\n'}),
}


@pytest.mark.parametrize("case", list(BAD_WEIGHTS_IN_A_BATCH_FILE.values()), ids=list(BAD_WEIGHTS_IN_A_BATCH_FILE))
def test_weights_a_batch_file_names_are_loaded_before_its_first_run(case, tmp_path, capsys, monkeypatch, no_work):
    # Before: the batch ran, every run with those weights failed, and a results folder of failures was left.
    _run_case(case, tmp_path, capsys, monkeypatch)


# ---- found by an audit of every subcommand (2026-11-28) ----------------------------------------------------

AUDIT_2026_11_28 = {
    "attack eval --signs with an empty name": Case(["attack", "eval", "--signs", "clean,,yang", "--out", "{tmp}/out"],
                                                   "has an empty name"),
    "attack eval --signs ''": Case(["attack", "eval", "--signs", "", "--out", "{tmp}/out"], "expects comma-separated names"),
    "attack eval: a corrupt texture after a good one": Case(
        ["attack", "eval", "--signs", "clean,{tmp}/bad.png", "--drives", "0", "--out", "{tmp}/out"], "not a PNG file",
        files={"bad.png": b"\x00garbage" * 32}),
    "attack eval --detectors with an unknown name": Case(["attack", "eval", "--detectors", "detector,foo", "--out", "{tmp}/out"],
                                                         "unknown name 'foo'"),
    "attack generate --cameras with an empty name": Case(
        ["attack", "generate", "--method", "yang", "--cameras", "front,,side", "--out", "{tmp}/a.png"], "has an empty name"),
    "attack generate --weights against a target without the own detector": Case(
        ["attack", "generate", "--method", "yang", "--detector", "coco", "--weights", "{tmp}/w.pt", "--out", "{tmp}/a.png"],
        "does not run it", files={"w.pt": b"weights"}),
    "attack sweep --rrd without --closed-loop": Case(
        ["attack", "sweep", "--method", "yang", "--budgets", "0.1", "--rrd", "all", "--out", "{tmp}/out"], "add --closed-loop"),
    "replay of a file that is no bag": Case(["replay", "{tmp}/image.mcap"], "cannot read bag",
                                            files={"image.mcap": b"\x89PNG\r\n\x1a\n" + b"\x00" * 32}),
    "replay of a file without the .mcap suffix": Case(["replay", "{tmp}/run.bag"], "does not end in .mcap",
                                                      files={"run.bag": b"\x89MCAP0\r\n" + b"\x00" * 32}),
}


@pytest.mark.parametrize("case", list(AUDIT_2026_11_28.values()), ids=list(AUDIT_2026_11_28))
def test_what_an_audit_found_is_refused_before_the_work(case, tmp_path, capsys, monkeypatch, no_work):
    _run_case(case, tmp_path, capsys, monkeypatch)


# ---- a third audit (2026-12-02): the results folder, checked before the first run ----------------------------
# `--workers 1` runs in this process, where `no_work` stops a run: before the fixes each case ran its runs (and
# failed them, exit 1) or wrote its report.

BOARD = """title = "tiny"
[defaults]
scenario = { town = "town07", placement = "standard", start_dist_m = 60 }
perception = { kind = "oracle" }
[conditions.clean]
scenario = { sign = "clean" }
[conditions.strongest]
scenario = { sign = "yang" }
[[defences]]
name = "baseline"
policy = { name = "baseline" }
adaptive = { scenario = { sign = "yang" } }
[[places]]
town = "town07"
placement = "standard"
quick_seeds = 1
"""
OTHER_SWEEP = SMOKE.read_text().replace("[40, 60]", "[30, 50]")
SWEEP_FOLDER = {"out/sweep.toml": SMOKE.read_text(), "out/results.jsonl": _record(0)}  # a smoke sweep's, stopped
BATCH = ["--workers", "1", "--no-progress"]
EXPERIMENT = 'seeds = 1\n[[cells]]\nname = "a"\nperception = { kind = "oracle" }\n'
REPRODUCED = {"e.toml": EXPERIMENT, "r/runs.jsonl": ""}  # a reproduction stopped before its first run

AUDIT_2026_12_02 = {
    "sweep --rrd all: OUT/rrd is a file": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", "--rrd", "all", *BATCH],
                                               "out/rrd is a file", files={"out/rrd": "x"}),
    "sweep --mcap all: OUT/mcap is a file": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", "--mcap", "all", *BATCH],
                                                 "out/mcap is a file", files={"out/mcap": "x"}),
    "sweep --rrd all: OUT/rrd/<sweep> is a file": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/out", "--rrd", "all", *BATCH], "rrd/sweep_smoke is a file",
        files={"out/rrd/sweep_smoke": "x"}),
    "leaderboard --rrd all: OUT/rrd is a file": Case(
        ["leaderboard", "{tmp}/b.toml", "--quick", "--out", "{tmp}/out", "--rrd", "all", *BATCH], "out/rrd is a file",
        files={"b.toml": BOARD, "out/rrd": "x"}),
    "reproduce --resume --rrd all: FOLDER/rrd is a file": Case(
        ["reproduce", "--experiments", "{tmp}/e.toml", "--resume", "{tmp}/r", "--rrd", "all", *BATCH], "r/rrd is a file",
        files={**REPRODUCED, "r/rrd": "x"}),
    "sweep --resume with another sweep file": Case(["sweep", "{tmp}/other.toml", "--out", "{tmp}/out", "--resume", *BATCH],
                                                   "another plan", files={**SWEEP_FOLDER, "other.toml": OTHER_SWEEP}),
    "leaderboard --resume of a sweep's folder": Case(
        ["leaderboard", "{tmp}/b.toml", "--quick", "--out", "{tmp}/out", "--resume", *BATCH],
        "holds the results of avsim sweep", files={**SWEEP_FOLDER, "b.toml": BOARD}),
    "sweep into a reproduction's folder": Case(["sweep", str(SMOKE), "--out", "{tmp}/r", *BATCH],
                                               "holds the results of avsim reproduce", files=REPRODUCED),
    "sweep --resume of a folder that does not exist": Case(
        ["sweep", str(SMOKE), "--out", "{tmp}/nowhere", "--resume", *BATCH], "no such folder"),
    "leaderboard --resume of a folder that does not exist": Case(
        ["leaderboard", "{tmp}/b.toml", "--quick", "--out", "{tmp}/nowhere", "--resume", *BATCH], "no such folder",
        files={"b.toml": BOARD}),
    "sweep: OUT/.avsim.lock is a folder": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", *BATCH], ".avsim.lock",
                                               files={"out/.avsim.lock/keep": ""}),
    "sweep: OUT/summary.md is a folder": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", "--rrd", "none", *BATCH],
                                              "summary.md is a folder", files={"out/summary.md/keep": ""}),
    "sweep: OUT/manifest.json is a folder": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", "--rrd", "none", *BATCH],
                                                 "manifest.json is a folder", files={"out/manifest.json/keep": ""}),
    "sweep: OUT/sweep.toml is a folder": Case(["sweep", str(SMOKE), "--out", "{tmp}/out", "--rrd", "none", *BATCH],
                                              "sweep.toml is a folder", files={"out/sweep.toml/keep": ""}),
    "leaderboard: OUT/leaderboard.png is a folder": Case(
        ["leaderboard", "{tmp}/b.toml", "--quick", "--out", "{tmp}/out", "--rrd", "none", *BATCH],
        "leaderboard.png is a folder", files={"b.toml": BOARD, "out/leaderboard.png/keep": ""}),
    "reproduce --resume: FOLDER/report.md is a folder": Case(
        ["reproduce", "--experiments", "{tmp}/e.toml", "--resume", "{tmp}/r", "--rrd", "none", *BATCH],
        "report.md is a folder", files={**REPRODUCED, "r/report.md/keep": ""}),
    "leaderboard --quick with every quick_seeds 0": Case(
        ["leaderboard", "{tmp}/b.toml", "--quick", "--out", "{tmp}/out", *BATCH], "no run to make",
        files={"b.toml": BOARD.replace("quick_seeds = 1", "quick_seeds = 0")}),
}


@pytest.mark.parametrize("case", list(AUDIT_2026_12_02.values()), ids=list(AUDIT_2026_12_02))
def test_the_results_folder_is_checked_before_the_first_run(case, tmp_path, capsys, monkeypatch, no_work):
    _run_case(case, tmp_path, capsys, monkeypatch)
