"""Command-line entry point: `avsim run`, `avsim detect`, `avsim snapshot`, `avsim sweep`, ... (`avsim --help`).

`main` is the one error boundary, and runs in this order for every subcommand:
1. the renderer MUJOCO_GL names is checked (`avsim.sensors.gl_backend`), before MuJoCo is imported;
2. every output path the subcommand declared (`avsim.outputs.add_output_argument`) is checked,
   before any work starts;
3. the subcommand runs.
What the user sees when something stops it is one line on stderr (`avsim.boundary`, shared
with the `python -m avsim....` entry points): exit 2 for bad input, 128 + the signal for Ctrl-C
(130), SIGTERM (143) or SIGHUP (129), 1 for a full disk or a bug. `--debug` (anywhere on the
command line) prints the full traceback as well.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from collections.abc import Iterator, Sequence
from typing import Any

from avsim.boundary import run_guarded
from avsim.cli_attack import add_attack_commands
from avsim.cli_overrides import merge_overrides, parse_set
from avsim.cli_recording import add_recording_modes
from avsim.cli_realism import add_realism_command
from avsim.config import LoopConfig, ScenarioConfig, check_seed
from avsim.errors import ConfigError
from avsim.library_output import quiet_rust_logs, route_mujoco_warnings_to_log
from avsim.outputs import FILE, FOLDER, PREFIX, add_output_argument, check_declared_outputs, check_output_file
from avsim.sensors.gl_backend import check_gl_backend
from avsim.validation import OneLineArgumentParser, config_flag, name_list_flag, number_flag
from avsim.workers import BATCH_HELP, DEFAULT_BATCH, quiet_resource_tracker

SEED_FLAG = config_flag(ScenarioConfig, "seed")
WORKERS_FLAG = number_flag(1, 1024, integer=True)
BATCH_FLAG = number_flag(1, 1024, integer=True)
# A finite integer whose range the command's own config declares (e.g. DataGenConfig, checked before any work).
INT_FLAG = number_flag(integer=True)


def _add_scenario_flags(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--town", help="town name (town03, town07, town10)")
    parser.add_argument("--placement", help="stop-sign placement: standard, near or far")
    parser.add_argument("--sign", help="stop-sign texture: 'clean', a name in textures/, a PNG path, or 'none' (no stop sign)")
    parser.add_argument("--speed-kmh", type=config_flag(ScenarioConfig, "speed_kmh"), help="cruise speed [km/h]")
    parser.add_argument("--seed", type=SEED_FLAG, help="random seed (start jitter)")
    parser.add_argument("--physics-dt-s", type=config_flag(LoopConfig, "physics_dt_s"), help="physics step [s] (default 0.002)")
    parser.add_argument("--control-dt-s", type=config_flag(LoopConfig, "control_dt_s"), help="control and sensing period [s] (default 0.05)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override any config key, e.g. --set policy.baseline_brake=0.9 (repeatable)")


def _flag_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The scenario flags and --set as one nested override mapping (--set wins over flags)."""
    flags = {
        "scenario": {"town": args.town, "placement": args.placement, "sign": args.sign, "speed_kmh": args.speed_kmh, "seed": args.seed},
        "loop": {"physics_dt_s": args.physics_dt_s, "control_dt_s": args.control_dt_s},
        "policy": {"name": getattr(args, "policy", None)},
        "perception": {"kind": getattr(args, "perception", None)},
    }
    overrides = {section: {k: v for k, v in values.items() if v is not None} for section, values in flags.items()}
    return merge_overrides(overrides, parse_set(args.set))


def _config_from_args(args: argparse.Namespace):
    from avsim.config import SimConfig, with_overrides

    return with_overrides(SimConfig(), _flag_overrides(args))


def _cmd_run(args: argparse.Namespace) -> int:
    from avsim.metrics import write_json_atomic
    from avsim.runner import run_recorded
    from avsim.summary import format_summary

    if args.config and Path(args.config).suffix == ".jsonl":
        from avsim.config import with_overrides
        from avsim.experiments.rerun_record import config_from_results

        # A batch's results file: the run's resolved config, as it ran; the flags apply on top.
        overrides = _flag_overrides(args)
        seed = args.seed if args.seed is not None else 0
        config = with_overrides(config_from_results(args.config, args.cell, seed), overrides)
    elif args.config:
        from avsim.config import with_overrides
        from avsim.experiments.spec import load_experiment

        # The flags and --set apply on top of the cell, as they do on top of the defaults
        # (same precedence: --set over flags over the cell).
        overrides = _flag_overrides(args)
        experiment = load_experiment(args.config)
        cell = experiment.cell(args.cell)
        # Run (cell, seed) exactly as the experiment's batch would, [vary] draws included;
        # the seed is 0 unless --seed or --set scenario.seed names another.
        seed = with_overrides(cell.config, overrides).scenario.seed
        config = with_overrides(experiment.config_for(cell, seed), overrides)
    elif args.cell is not None:
        raise ConfigError("--cell needs --config FILE.toml (the experiment file that holds the cell)")
    else:
        config = _config_from_args(args)
    from avsim.experiments.spec import check_run_names

    check_run_names(config)  # every name and the sign texture, before the scene is built
    if args.mcap:
        from avsim.recording.ros_types import require_rosbags

        require_rosbags()  # before the run, not after it
    output = run_recorded(config, rrd_path=args.rrd, mp4_path=args.mp4, mcap_path=args.mcap,
                          mcap_images=args.mcap_images)
    result, wall_s = output.result, output.wall_s
    print(format_summary(result, wall_s))
    if args.json is not None:
        write_json_atomic(args.json, result.to_json_dict())
        print(f"  result written to {args.json}")
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from avsim.experiments.reproduce import reproduce

    paths = [Path(p) for p in args.experiments] if args.experiments else None
    out = reproduce(args.out, quick=args.quick, workers=args.workers, experiment_paths=paths, progress=not args.no_progress,
                    backend=args.backend, address=args.address, batch=args.batch, everything=args.all, yes=args.yes,
                    rrd=args.rrd_mode, mcap=args.mcap_mode)
    print((out / "report.md").read_text())
    print(f"wrote {out}/report.md, runs.jsonl and figures" + (f"; recordings (--rrd {args.rrd_mode}, --mcap {args.mcap_mode}) "
                                                             f"under {out}/rrd/ and {out}/mcap/" if args.rrd_mode != "none" or args.mcap_mode != "none" else ""))
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from avsim.experiments.sweep import load_sweep, run_sweep

    sweep = load_sweep(args.file, yes=args.yes)  # checks the size, then every grid value, before anything runs
    out = run_sweep(sweep, args.out, workers=args.workers, resume=args.resume, progress=not args.no_progress,
                    backend=args.backend, address=args.address, batch=args.batch, rrd=args.rrd_mode, mcap=args.mcap_mode)
    print((out / "summary.md").read_text())
    print(f"wrote {out}/results.jsonl, summary.md and safety_map.png")
    return 0


def _cmd_leaderboard(args: argparse.Namespace) -> int:
    from avsim.experiments.leaderboard import DEFAULT_FILE, load_leaderboard
    from avsim.experiments.leaderboard_run import run_leaderboard

    board = load_leaderboard(args.file or DEFAULT_FILE)  # checks every run before anything runs or is written
    out = run_leaderboard(board, args.out, quick=args.quick, workers=args.workers, resume=args.resume,
                          progress=not args.no_progress, backend=args.backend, address=args.address, batch=args.batch,
                          rrd=args.rrd_mode, mcap=args.mcap_mode)
    print((out / "leaderboard.md").read_text())
    print(f"wrote {out}/leaderboard.md, leaderboard.png and results.jsonl")
    return 0


def _cmd_snapshot(args: argparse.Namespace) -> int:
    from avsim.snapshot import check_snapshot_distance, save_snapshot, save_town_strip
    from avsim.world.towns import TOWNS

    config = _config_from_args(args)
    check_snapshot_distance(args.dist_m)
    if args.towns is None:
        if args.strip:
            raise ConfigError("--strip needs --towns (e.g. --towns town07,town03,town10): it puts their front cameras side by side")
        paths = save_snapshot(config, args.dist_m, args.out)
    else:
        towns = args.towns  # a non-empty list of names (name_list_flag)
        for town in towns:
            TOWNS.get(town)  # every name checked before anything renders
        if not args.strip:
            raise ConfigError("--towns goes with --strip (one picture of the towns' front cameras side by side); "
                              "for one town's cameras use --town")
        paths = [save_town_strip(config, towns, args.dist_m, args.out)]
    for path in paths:
        print(f"wrote {path}")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    if args.profile:
        from avsim.bench_profile import run_profile

        run_profile(quick=args.quick)
        return 0
    if args.recording:
        from avsim.recording.overhead import print_recording_overhead

        print_recording_overhead(repeats=1 if args.quick else 3)
        return 0
    from avsim.bench import run_benchmarks

    run_benchmarks(quick=args.quick)
    return 0


def _cmd_make_data(args: argparse.Namespace) -> int:
    from avsim.perception.datagen import DataGenConfig, make_dataset

    config = DataGenConfig(n_train=args.train, n_val=args.val, images_per_scene=args.images_per_scene,
                           seed=args.seed, workers=args.workers, max_dist_m=args.max_dist_m, label_format=args.format)
    out = make_dataset(args.out, config, overwrite=args.overwrite)
    print(f"wrote {config.n_train} training and {config.n_val} validation images to {out} ({config.label_format} labels)")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from avsim.perception.detector.train import run_from_args

    return run_from_args(args)


def _cmd_export(args: argparse.Namespace) -> int:
    if args.format == "onnx":
        from avsim.perception.detector.export_onnx import export_onnx
        from avsim.perception.detector.weights import resolve_weights_path

        out = check_output_file(args.out or "models/sign_detector.onnx", "--out")  # the default is checked too
        path = export_onnx(resolve_weights_path(args.checkpoint or ""), out)
    else:
        from avsim.perception.detector.weights import export_weights

        if not args.checkpoint:
            raise ConfigError("avsim detector export --format pt needs --checkpoint (written by `avsim detector train`)")
        path = export_weights(args.checkpoint, check_output_file(args.out or "models/sign_detector.pt", "--out"))
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from avsim.perception.detector.weights import resolve_weights_path
    from avsim.perception.detector.infer import SignDetectorRunner
    from avsim.perception.evaluation import evaluate, write_report

    weights = resolve_weights_path(args.weights)
    # Score every box down to a low confidence: AP needs the whole ranking.
    runner = SignDetectorRunner(weights, conf_threshold=0.01)
    report = evaluate(runner.detect, args.data, conf_threshold=args.conf, split=args.split, limit=args.limit,
                      progress=not args.no_progress)
    report_path, plot_path = write_report(report, args.out, f"Sign detector {weights.name} on {args.data} ({args.split})")
    print(report_path.read_text())
    print(f"wrote {report_path} and {plot_path}")
    return 0


def _cmd_detect(args: argparse.Namespace) -> int:
    import json

    from avsim.perception.images import detect_images

    from avsim.config import SimConfig, with_overrides

    flags = {"perception": {"kind": args.perception}} if args.perception else {}
    config = with_overrides(SimConfig(), merge_overrides(flags, parse_set(args.set))).perception
    for record in detect_images(config, [Path(p) for p in args.images]):
        print(json.dumps(record), flush=True)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    import json

    from avsim.metrics import write_text_atomic
    from avsim.recording.ros_replay import replay

    overrides = parse_set(args.set).get("perception", {})
    if args.perception:
        overrides = {**overrides, "kind": args.perception}
    lines = (json.dumps(record) for record in replay(args.bag, overrides))
    if args.out is None:
        for line in lines:
            print(line, flush=True)
        return 0
    text = "".join(line + "\n" for line in lines)  # all or nothing: written once every image is done
    write_text_atomic(args.out, text)
    print(f"wrote {text.count(chr(10))} image records to {args.out}")
    return 0


DETECT_HELP = """Run a perception on image files and print one JSON line per image:
{"image", "width", "height", "perception", "detections": [{"class", "confidence", "box_xyxy_px"}]}
with every detection at or above perception.min_confidence, highest first, boxes in the
image's own pixels. The whole image is searched (the closed loop's regions of interest and
its min_box_height_px range limit do not apply).

Images of any size:
  detector  letterboxed into its 640x480 input (aspect kept, grey padding), boxes mapped back;
  coco      by perception.coco_input: resize squeezes the whole image to 512x512 as
            @vladmandic/human does (aspect not kept); crop runs the network on the image at
            its own resolution (padded to a multiple of 32; slow and memory-hungry for
            large photos); upscale enlarges it by perception.coco_upscale first;
  yolo      by perception.yolo_input, as coco, but resize squeezes it to the cfg's 416x416
            (YOLOv3-tiny; perception.yolo_cfg/yolo_weights/yolo_names for your own files);
  onnx      letterboxed into the model's own input size (640x640 if it is dynamic);
  ensemble  detector and coco on the same image, each detection with its "source".
perception.purify (jpeg, median) cleans each image before the network sees it.
The oracle needs a simulated scene and cannot run on an image."""


def _add_detector_commands(sub) -> None:
    detector = sub.add_parser("detector", help="make data for, train and evaluate the sign detector")
    dsub = detector.add_subparsers(dest="detector_command", required=True)
    data = dsub.add_parser("make-data", help="render labelled sign images (boxes from segmentation)")
    add_output_argument(data, "--out", kind=FOLDER, default="data/signs", help="dataset directory (default data/signs)")
    data.add_argument("--train", type=INT_FLAG, default=6000, help="training images")
    data.add_argument("--val", type=INT_FLAG, default=1000, help="validation images (held-out town seed and lighting)")
    data.add_argument("--images-per-scene", type=INT_FLAG, default=25)
    data.add_argument("--seed", type=SEED_FLAG, default=0)
    data.add_argument("--workers", type=INT_FLAG, default=min(2, os.cpu_count() or 1))
    data.add_argument("--max-dist-m", type=number_flag(unit="m"), default=80.0,
                      help="farthest target sign [m] (default 80; 160 to measure the perception's range)")
    data.add_argument("--format", choices=("jsonl", "coco", "yolo"), default="jsonl",
                      help="labels: jsonl (default, read by detector train/eval), coco (annotations/instances_SPLIT.json) "
                           "or yolo (labels/SPLIT/*.txt and data.yaml, for ultralytics)")
    data.add_argument("--overwrite", action="store_true", help="replace an existing dataset directory")
    data.set_defaults(func=_cmd_make_data)

    from avsim.perception.detector.train_args import add_train_arguments

    train = dsub.add_parser("train", help="train the detector on a generated dataset (resumable checkpoint)")
    add_train_arguments(train)
    train.set_defaults(func=_cmd_train)

    export = dsub.add_parser("export", help="strip a training checkpoint to deployable weights (e.g. models/sign_detector.pt), "
                                            "or write the detector as ONNX in the YOLOv8/YOLO11 output layout")
    export.add_argument("--format", choices=("pt", "onnx"), default="pt",
                        help="pt: deployable PyTorch weights (default); onnx: (1, 3, 480, 640) RGB in [0, 1] -> "
                             "(1, 4 + 3, N) cx, cy, w, h, class scores, for --perception onnx (needs avsim[onnx])")
    export.add_argument("--checkpoint", help="checkpoint written by `avsim detector train` (required for pt; for onnx "
                                             "the default is the shipped models/sign_detector.pt)")
    add_output_argument(export, "--out", kind=FILE,
                        help="file to write (default models/sign_detector.pt, or models/sign_detector.onnx)")
    export.set_defaults(func=_cmd_export)

    evaluate = dsub.add_parser("eval", help="score weights on the held-out split; writes report.md and a plot")
    evaluate.add_argument("--weights", default="", help="weights file (default: the shipped models/sign_detector.pt)")
    evaluate.add_argument("--data", default="data/signs", help="dataset directory (default data/signs)")
    evaluate.add_argument("--split", default="val", choices=("val", "train"))
    evaluate.add_argument("--conf", type=number_flag(0, 1, lo_open=True, hi_open=True), default=0.5,
                          help="confidence threshold for recall and false positives")
    evaluate.add_argument("--limit", type=number_flag(1, None, integer=True), help="score only the first N images")
    add_output_argument(evaluate, "--out", kind=FOLDER, default="results/detector_eval", help="report directory")
    evaluate.add_argument("--no-progress", action="store_true", help="no progress bar")
    evaluate.set_defaults(func=_cmd_eval)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineArgumentParser(prog="avsim", description="Closed-loop stop-sign attack and defence simulator on MuJoCo.")
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="drive one scenario and print its summary")
    _add_scenario_flags(run)
    run.add_argument("--policy", help="braking policy: baseline, adjusted, side_camera, combined, study_stack, temporal_vote, "
                                      "map_prior, autopilot")
    run.add_argument("--perception", help="perception: detector (trained network on RGB), coco (a COCO-trained CenterNet), "
                                          "yolo (YOLOv3-tiny, COCO), ensemble (both on each frame), onnx (your YOLO-layout ONNX detector) or oracle "
                                          "(ground-truth boxes)")
    add_output_argument(run, "--json", kind=FILE, help="write the result record to this JSON file")
    add_output_argument(run, "--rrd", kind=FILE,
                        help="record the run (camera images, detections, car pose, metrics) to this rerun .rrd file")
    add_output_argument(run, "--mp4", kind=FILE, suffix=".mp4",
                        help="write a video of the front camera with the detections, speed and brake to this .mp4 file")
    add_output_argument(run, "--mcap", kind=FILE, suffix=".mcap",
                        help="write the run as a ROS 2 bag in MCAP storage (images, camera_info, detections, odom, tf, "
                             "commands; needs avsim[ros]; docs/ros.md)")
    run.add_argument("--mcap-images", choices=("png", "jpeg"), default="png",
                     help="how --mcap stores camera images: png (lossless, the default) or jpeg (quality 90, smaller)")
    run.add_argument("--config", help="experiment file (experiments/*.toml), or a batch's results file (results.jsonl, "
                                      "runs.jsonl): run one of its cells as the batch ran it; the flags above apply on top")
    run.add_argument("--cell", help="name of the cell to run from --config (default: the first cell of an experiment file)")
    run.set_defaults(func=_cmd_run)

    rep = sub.add_parser("reproduce", help="run the study's tables and figures; writes results/<timestamp>/ with report.md")
    rep.add_argument("--quick", action="store_true", help="one seed per cell, for a smoke check")
    rep.add_argument("--all", action="store_true",
                     help="also every other experiment file: the sensitivity, the COCO network's closed loop and the "
                          "attack-success files (hours on 2 cores; the leaderboard is `avsim leaderboard`)")
    rep.add_argument("--workers", type=WORKERS_FLAG, help="runs at once: worker processes, or the local Ray cluster's CPUs "
                                                  "(default: one per core); with --address, at most this many in flight")
    rep.add_argument("--backend", choices=("local", "ray"), default="local",
                     help="local: a pool of processes on this machine (default); ray: Ray tasks (pip install 'avsim[ray]')")
    rep.add_argument("--batch", type=BATCH_FLAG, default=DEFAULT_BATCH, metavar="N", help=BATCH_HELP)
    rep.add_argument("--address", help="Ray cluster to run on, e.g. auto or HOST:6379 (with --backend ray)")
    add_output_argument(rep, "--out", kind=FOLDER, default="results", help="folder in which the timestamped results folder is made")
    rep.add_argument("--experiments", nargs="+", metavar="FILE",
                     help="experiment files to run instead of the study's (experiments/*.toml)")
    rep.add_argument("--no-progress", action="store_true", help="no progress bar")
    rep.add_argument("--yes", action="store_true", help="run more than 10,000 runs (refused without it)")
    add_recording_modes(rep)
    rep.set_defaults(func=_cmd_reproduce)

    swp = sub.add_parser("sweep", help="run every combination of a sweep file's grid; writes results.jsonl, summary.md "
                                       "and safety_map.png")
    swp.add_argument("file", help="sweep file (experiments/sweeps/*.toml)")
    add_output_argument(swp, "--out", kind=FOLDER, required=True, help="results folder")
    swp.add_argument("--workers", type=WORKERS_FLAG,
                     help="runs at once: worker processes, or the local Ray cluster's CPUs (default: one per core); "
                          "with --address, at most this many runs in flight (default: the cluster's CPUs)")
    swp.add_argument("--backend", choices=("local", "ray"), default="local",
                     help="local: a pool of processes on this machine (default); ray: Ray tasks, on a local "
                          "cluster or the one at --address (pip install 'avsim[ray]')")
    swp.add_argument("--batch", type=BATCH_FLAG, default=DEFAULT_BATCH, metavar="N", help=BATCH_HELP)
    swp.add_argument("--address", help="Ray cluster to run on, e.g. auto or HOST:6379 (with --backend ray)")
    swp.add_argument("--resume", action="store_true",
                     help="keep the ok runs already in OUT/results.jsonl and run only the others")
    swp.add_argument("--no-progress", action="store_true", help="no progress bar")
    swp.add_argument("--yes", action="store_true", help="run a grid of more than 10,000 runs (refused without it)")
    add_recording_modes(swp)
    swp.set_defaults(func=_cmd_sweep)

    board = sub.add_parser("leaderboard", help="every defence against the attacks and on roads that need no stop; "
                                               "writes leaderboard.md, leaderboard.png and results.jsonl")
    board.add_argument("file", nargs="?", help="leaderboard file (default experiments/leaderboards/defences.toml)")
    add_output_argument(board, "--out", kind=FOLDER, default="results/leaderboard", help="results folder")
    board.add_argument("--quick", action="store_true", help="the file's quick subset (quick_seeds per place and scenario)")
    board.add_argument("--workers", type=WORKERS_FLAG,
                       help="runs at once: worker processes, or the local Ray cluster's CPUs (default: one per core)")
    board.add_argument("--backend", choices=("local", "ray"), default="local",
                       help="local: a pool of processes on this machine (default); ray: Ray tasks (pip install 'avsim[ray]')")
    board.add_argument("--batch", type=BATCH_FLAG, default=DEFAULT_BATCH, metavar="N", help=BATCH_HELP)
    board.add_argument("--address", help="Ray cluster to run on, e.g. auto or HOST:6379 (with --backend ray)")
    board.add_argument("--resume", action="store_true", help="keep the ok runs already in OUT/results.jsonl and run the rest")
    board.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_recording_modes(board)
    board.set_defaults(func=_cmd_leaderboard)

    snap = sub.add_parser("snapshot", help="save front and side camera images at a distance from the stop line")
    _add_scenario_flags(snap)
    snap.add_argument("--dist-m", type=number_flag(unit="m"), default=30.0, help="front bumper to stop line [m]")
    snap.add_argument("--towns", type=name_list_flag(), help="with --strip: comma-separated towns whose front cameras are put side by side")
    snap.add_argument("--strip", action="store_true",
                      help="write PREFIX.png: the front camera of each of --towns, side by side at half size")
    add_output_argument(snap, "--out", kind=PREFIX, suffixes=("_front.png", "_side.png", ".png"), default="snapshot",
                        help="output prefix; writes PREFIX_front.png and PREFIX_side.png (PREFIX.png with --strip)")
    snap.set_defaults(func=_cmd_snapshot)

    detect = sub.add_parser("detect", help="run a perception on image files; one JSON line of detections per image",
                            description=DETECT_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    detect.add_argument("images", nargs="+", metavar="IMAGE", help="image files (PNG, JPEG, ...)")
    detect.add_argument("--perception", help="detector (default), coco, yolo, ensemble or onnx")
    detect.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override any config key, e.g. --set perception.coco_input=resize (repeatable)")
    detect.set_defaults(func=_cmd_detect)

    rep_bag = sub.add_parser("replay", help="run a perception over a ROS bag's camera images; one JSON line per image",
                             description="Run a pixel perception over every sensor_msgs/CompressedImage of a ROS bag "
                                         "(.mcap, a ROS 2 bag folder or a ROS 1 .bag; needs avsim[ros]), as the closed "
                                         "loop runs it (region of interest, range limit). One JSON line per image: topic, "
                                         "camera, stamp_ns, width, height, perception, detections. The settings start from "
                                         "the bag's own avsim run, if it is one (docs/ros.md).")
    rep_bag.add_argument("bag", help="the bag: an .mcap file or a bag folder")
    rep_bag.add_argument("--perception", help="detector, coco, ensemble or onnx (default: the bag's own, or detector)")
    rep_bag.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="override a perception key, e.g. --set perception.min_confidence=0.3 (repeatable)")
    add_output_argument(rep_bag, "--out", kind=FILE, help="write the JSON lines to this file instead of printing them")
    rep_bag.set_defaults(func=_cmd_replay)

    bench = sub.add_parser("bench", help="print physics, rendering and closed-loop speed on this machine")
    bench.add_argument("--quick", action="store_true", help="fewer repetitions")
    bench.add_argument("--profile", action="store_true",
                       help="where one run's and one batch's time goes, stage by stage, beside the speed targets")
    bench.add_argument("--recording", action="store_true",
                       help="only what --rrd and --mcap add to a run: wall time and file size (docs/recording.md)")
    bench.set_defaults(func=_cmd_bench)
    _add_detector_commands(sub)
    add_attack_commands(sub)
    add_realism_command(sub)
    parser.add_argument("--debug", action="store_true", help="on an error, print the full traceback too")
    for _, child in iter_parsers(parser):
        if child is not parser:
            # SUPPRESS: a subcommand without --debug must not reset the top-level flag.
            child.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return parser


def iter_parsers(parser: argparse.ArgumentParser, name: str = "avsim") -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every parser of the command line, subcommands included: ("avsim attack generate", parser), ..."""
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, child in action.choices.items():
                yield from iter_parsers(child, f"{name} {sub_name}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the `avsim` command line; returns the exit status (see the module docstring)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # argparse printed its one line (or --help); its status, as for any refusal
        return exc.code if isinstance(exc.code, int) else 2

    def command() -> int:
        check_gl_backend()  # before anything imports MuJoCo, which fails at import on a bad MUJOCO_GL
        route_mujoco_warnings_to_log()  # its instability printout would precede the one-line PhysicsError
        quiet_rust_logs()  # rerun's own lines about a full disk would precede the one-line OutputError
        quiet_resource_tracker()  # a SIGKILLed batch leaves no multiprocessing warning on the terminal
        check_declared_outputs(args)  # before any work: a bad path never costs a finished run
        if getattr(args, "seed", None) is not None:  # every subcommand's --seed, one range
            check_seed(args.seed, "--seed")
        return args.func(args)

    return run_guarded(command, prog="avsim", debug=bool(getattr(args, "debug", False)))


if __name__ == "__main__":
    raise SystemExit(main())
