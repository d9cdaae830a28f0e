"""`avsim run`: drive one scenario (from the flags, an experiment file's cell or a batch's results
file) and print its summary."""

from __future__ import annotations

import argparse
from pathlib import Path

from avsim.cli.flags import add_scenario_flags, add_setting_flag, config_from_args, flag_overrides, refuse_setting_clash
from avsim.errors import ConfigError
from avsim.outputs import FILE, add_input_argument, add_output_argument
from avsim.realism.settings import BASELINE, SETTINGS


def _cmd_run(args: argparse.Namespace) -> int:
    from avsim.metrics import write_json_atomic
    from avsim.runner import run_recorded
    from avsim.summary import format_summary

    setting = SETTINGS[args.setting]
    if args.config and Path(args.config).suffix == ".jsonl":
        from avsim.config import with_overrides
        from avsim.experiments.rerun_record import config_from_results

        if args.setting != BASELINE:
            raise ConfigError("--setting applies to an experiment file or to the flags; a results file's runs already "
                              "carry the render setting they ran under, so leave out --setting")
        # A batch's results file: the run's resolved config, as it ran; the flags apply on top.
        overrides = flag_overrides(args)
        seed = args.seed if args.seed is not None else 0
        base = config_from_results(args.config, args.cell, seed)
        config = with_overrides(base, overrides)
    elif args.config:
        from avsim.config import with_overrides
        from avsim.experiments.render_setting import under_setting
        from avsim.experiments.spec import load_experiment

        # The flags and --set apply on top of the cell, as they do on top of the defaults
        # (same precedence: --set over flags over the cell).
        overrides = flag_overrides(args)
        refuse_setting_clash(setting, overrides)
        experiment = under_setting(load_experiment(args.config), setting)  # as `avsim reproduce --setting` runs it
        cell = experiment.cell(args.cell)
        # Run (cell, seed) exactly as the experiment's batch would, [vary] draws included;
        # the seed is 0 unless --seed or --set scenario.seed names another.
        seed = with_overrides(cell.config, overrides).scenario.seed
        base = experiment.config_for(cell, seed)
        config = with_overrides(base, overrides)
    elif args.cell is not None:
        raise ConfigError("--cell needs --config FILE.toml (the experiment file that holds the cell)")
    else:
        base = None  # the defaults: a clean stop sign
        config = config_from_args(args, setting)
    from avsim.config import NO_SIGN
    from avsim.config_owners import check_read, set_keys
    from avsim.experiments.spec import check_renderer, check_run_names

    check_run_names(config)  # every name and the sign texture, before the scene is built
    check_renderer(config)
    # A key set here that this run does not read: its policy, its perception, or what it draws
    # (a recorder draws the front camera in colour, whatever the perception).
    # With --config, the seed picks the run of the file (its [vary] draw, its record), so it is read.
    recorded = bool(args.rrd or args.mp4 or args.mcap)
    # A sign texture set over a run with no stop sign puts one there, which every run reads
    # (over another texture it changes only colour pixels: read where colour is drawn).
    always_read = {"scenario.seed"} if args.config else set()
    if base is not None and base.scenario.sign == NO_SIGN:
        always_read.add("scenario.sign")
    check_read(config, set_keys(flag_overrides(args)) - always_read, recorded=recorded)
    if args.mcap_images is not None and not args.mcap:
        raise ConfigError(f"--mcap-images {args.mcap_images} says how --mcap stores camera images; add --mcap FILE, "
                          "or drop it")
    if args.mcap:
        from avsim.recording.ros_types import require_rosbags

        require_rosbags()  # before the run, not after it
    output = run_recorded(config, rrd_path=args.rrd, mp4_path=args.mp4, mcap_path=args.mcap,
                          mcap_images=args.mcap_images or "png")
    result, wall_s = output.result, output.wall_s
    print(format_summary(result, wall_s))
    if args.json is not None:
        write_json_atomic(args.json, result.to_json_dict())
        print(f"  result written to {args.json}")
    return 0


def add_commands(sub) -> None:
    """Add `avsim run` to the subcommands `sub`."""
    run = sub.add_parser("run", help="drive one scenario and print its summary")
    add_scenario_flags(run)
    run.add_argument("--policy", help="braking policy: baseline, adjusted, side_camera, combined, study_stack, temporal_vote, "
                                      "map_prior, autopilot")
    run.add_argument("--perception", help="perception: detector (trained network on RGB), coco (a COCO-trained CenterNet), "
                                          "yolo (YOLOv3-tiny, COCO), ensemble (both on each frame), onnx (your YOLO-layout ONNX detector) or oracle "
                                          "(ground-truth boxes)")
    add_output_argument(run, "--json", kind=FILE, help="write the result record to this JSON file")
    add_output_argument(run, "--rrd", kind=FILE, suffix=".rrd",
                        help="record the run (camera images, detections, car pose, metrics) to this rerun .rrd file")
    add_output_argument(run, "--mp4", kind=FILE, suffix=".mp4",
                        help="write a video of the front camera with the detections, speed and brake to this .mp4 file")
    add_output_argument(run, "--mcap", kind=FILE, suffix=".mcap",
                        help="write the run as a ROS 2 bag in MCAP storage (images, camera_info, detections, odom, tf, "
                             "commands; needs avsim[ros]; docs/ros.md)")
    run.add_argument("--mcap-images", choices=("png", "jpeg"),
                     help="how --mcap stores camera images: png (lossless, the default) or jpeg (quality 90, smaller)")
    add_input_argument(run, "--config", help="experiment file (experiments/*.toml), or a batch's results file (results.jsonl, "
                                      "runs.jsonl): run one of its cells as the batch ran it; the flags above apply on top")
    run.add_argument("--cell", help="name of the cell to run from --config (default: the first cell of an experiment file)")
    add_setting_flag(run, "the run (the flags' scenario or the file's cell, as `avsim reproduce --setting` runs it)",
                     "a key it sets may not be set again by --set or the file")
    run.set_defaults(func=_cmd_run)
