"""`avsim detector make-data | train | export | eval`: the sign detector's data, training, export
and evaluation."""

from __future__ import annotations

import argparse
import os

from avsim.cli.flags import INT_FLAG, SEED_FLAG
from avsim.errors import ConfigError
from avsim.experiments.output_lock import locked_output, locked_sibling
from avsim.outputs import FILE, FOLDER, add_input_argument, add_output_argument, check_output_file
from avsim.realism.settings import SETTINGS
from avsim.validation import number_flag


def _cmd_make_data(args: argparse.Namespace) -> int:
    from avsim.perception.datagen import DataGenConfig, make_dataset

    config = DataGenConfig(n_train=args.train, n_val=args.val, images_per_scene=args.images_per_scene,
                           seed=args.seed, workers=args.workers, max_dist_m=args.max_dist_m, label_format=args.format,
                           setting=args.setting, setting_overrides=SETTINGS[args.setting].config_overrides())
    with locked_sibling(args.out, f"avsim detector make-data --out {args.out}"):  # one writer at a time
        out = make_dataset(args.out, config, overwrite=args.overwrite)
    under = "" if config.setting == "baseline" else f", rendered under {config.setting}"
    print(f"wrote {config.n_train} training and {config.n_val} validation images to {out} ({config.label_format} labels{under})")
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from avsim.perception.detector.train import run_from_args

    return run_from_args(args)


def _cmd_export(args: argparse.Namespace) -> int:
    if args.format == "onnx":
        from avsim.perception.detector.export_onnx import export_onnx
        from avsim.perception.detector.weights import resolve_weights_path

        # The default is checked too; an ONNX file under another ending would be read as something else.
        out = check_output_file(args.out or "models/sign_detector.onnx", "--out (--format onnx)", suffix=".onnx")
        path = export_onnx(resolve_weights_path(args.checkpoint or ""), out)
    else:
        from avsim.perception.detector.weights import export_weights

        if not args.checkpoint:
            raise ConfigError("avsim detector export --format pt needs --checkpoint (written by `avsim detector train`)")
        out = check_output_file(args.out or "models/sign_detector.pt", "--out")
        if out.suffix.lower() == ".onnx":  # PyTorch weights (.pt, .pth) that `--perception onnx` would refuse as corrupt
            raise ConfigError(f"--out '{out}' ends in .onnx, and --format pt writes PyTorch weights; add --format onnx, "
                              "or give --out a .pt ending")
        path = export_weights(args.checkpoint, out)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from avsim.perception.detector.weights import resolve_weights_path, training_sentence
    from avsim.perception.detector.infer import SignDetectorRunner
    from avsim.perception.evaluation import evaluate, write_report

    weights = resolve_weights_path(args.weights)
    # Score every box down to a low confidence: AP needs the whole ranking.
    runner = SignDetectorRunner(weights, conf_threshold=0.01)
    with locked_output(args.out, f"avsim detector eval --out {args.out}"):  # one writer at a time
        report = evaluate(runner.detect, args.data, conf_threshold=args.conf, split=args.split, limit=args.limit,
                          progress=not args.no_progress)
        report_path, plot_path = write_report(report, args.out,
                                              f"Sign detector {weights.name} on {args.data} ({args.split})",
                                              about=training_sentence(runner.meta))
    print(report_path.read_text())
    print(f"wrote {report_path} and {plot_path}")
    return 0


def add_commands(sub) -> None:
    """Add `avsim detector make-data | train | export | eval` to the subcommands `sub`."""
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
    data.add_argument("--setting", choices=tuple(SETTINGS), default="baseline", metavar="NAME",
                      help=f"render every image under one of `avsim realism`'s settings: {', '.join(SETTINGS)} (default "
                           "baseline, the default renders); the views are the same under any setting")
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
    add_input_argument(export, "--checkpoint", help="checkpoint written by `avsim detector train` (required for pt; for onnx "
                                             "the default is the shipped models/sign_detector.pt)")
    add_output_argument(export, "--out", kind=FILE,
                        help="file to write (default models/sign_detector.pt, or models/sign_detector.onnx)")
    export.set_defaults(func=_cmd_export)

    evaluate = dsub.add_parser("eval", help="score weights on the held-out split; writes report.md and a plot")
    add_input_argument(evaluate, "--weights", default="", help="weights file (default: the shipped models/sign_detector.pt)")
    add_input_argument(evaluate, "--data", default="data/signs", help="dataset directory (default data/signs)")
    evaluate.add_argument("--split", default="val", choices=("val", "train"))
    evaluate.add_argument("--conf", type=number_flag(0, 1, lo_open=True, hi_open=True), default=0.5,
                          help="confidence threshold for recall and false positives")
    evaluate.add_argument("--limit", type=number_flag(1, None, integer=True), help="score only the first N images")
    add_output_argument(evaluate, "--out", kind=FOLDER, default="results/detector_eval", help="report directory")
    evaluate.add_argument("--no-progress", action="store_true", help="no progress bar")
    evaluate.set_defaults(func=_cmd_eval)
