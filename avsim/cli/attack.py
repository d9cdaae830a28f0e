"""`avsim attack generate | eval | sweep`: the attack subcommands and their arguments.

`avsim.cli.command` adds them to its parser (`add_commands`) and is their error boundary: every
check here raises a one-line ConfigError before anything is rendered or optimised.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from avsim.attacks.defaults import CLOSED_LOOP_METHODS, DEFAULT_ATTACKED_SPEED_KMH, DEFAULT_THREADS
from avsim.cli.flags import SEED_FLAG
from avsim.cli.overrides import parse_set
from avsim.cli.recording_modes import add_recording_modes
from avsim.config import ScenarioConfig, check_seed
from avsim.errors import ConfigError
from avsim.experiments.output_lock import locked_output
from avsim.outputs import FILE, FOLDER, add_input_argument, add_output_argument
from avsim.realism.settings import SETTINGS
from avsim.validation import config_flag, name_list_flag, number_flag, number_list_flag

STEPS_FLAG = number_flag(1, 100_000, integer=True)
# The perceptions `attack eval --detectors` measures a texture under: the networks that look at pixels.
EVAL_DETECTORS = ("detector", "coco", "yolo", "nanodet")


def _cmd_attack_generate(args: argparse.Namespace) -> int:
    from avsim.attacks.generate import (check_hyperparameters, check_ssim_floor, default_bank, generate, generate_from,
                                        prepare, purify_keys, read_recipe)
    from avsim.attacks.targets import TARGET_MEMBERS, TARGET_NAMES

    if args.from_json:
        # Everything comes from the record; flags that would change the texture are refused.
        given = [flag for flag, value in (("--method", args.method), ("--steps", args.steps),
                                          ("--views-per-step", args.views_per_step), ("--set", args.set),
                                          ("--detector", args.detector), ("--cameras", args.cameras),
                                          ("--ssim-floor", args.ssim_floor), ("--seed", args.seed),
                                          ("--purify", args.purify), ("--speed-kmh", args.speed_kmh),
                                          ("--threads", args.threads)) if value not in (None, [])]
        if given:
            raise ConfigError(f"--from regenerates a texture from its record alone; drop {', '.join(given)}")
        read_recipe(args.from_json)  # a bad record fails before anything is rendered
        _, record = generate_from(args.from_json, args.out, args.weights)
    else:
        if not args.method:
            raise ConfigError("avsim attack generate needs --method NAME (or --from textures/NAME.json)")
        hyper = {k: v for k, v in (("steps", args.steps), ("views_per_step", args.views_per_step)) if v is not None}
        hyper.update(parse_set(args.set))
        seed = 0 if args.seed is None else args.seed
        check_seed(seed, "--seed")
        check_hyperparameters(args.method, seed, hyper)
        detector = args.detector or "detector"
        if detector not in TARGET_NAMES:
            raise ConfigError(f"--detector must be one of {', '.join(TARGET_NAMES)}, got '{detector}'")
        if args.weights and "detector" not in TARGET_MEMBERS[detector]:
            raise ConfigError(f"--weights sets the own detector's weights, and --detector {detector} does not run it; "
                              "drop --weights, or attack a target that holds the own detector")
        ssim_floor = args.ssim_floor  # None: the method's own floor, or 0.7
        if ssim_floor is not None:
            check_ssim_floor(ssim_floor)
        # The spec checks the camera names, so a bad one fails before anything is rendered.
        cameras = tuple(args.cameras or ("front",))
        if args.speed_kmh is not None and args.method not in CLOSED_LOOP_METHODS:
            raise ConfigError(f"--speed-kmh spaces the drive-by methods' frames ({', '.join(CLOSED_LOOP_METHODS)}); "
                              f"--method {args.method} draws its views at random distances, so drop --speed-kmh")
        speed_kmh = DEFAULT_ATTACKED_SPEED_KMH if args.speed_kmh is None else args.speed_kmh
        bank_spec, photometric = default_bank(args.method, cameras, speed_kmh)
        purify = purify_keys(args.purify or "none")
        _, record = generate(args.method, args.out, seed=seed,
                             setup=prepare(args.weights, bank_spec, detector, photometric, purify),
                             hyperparameters=hyper, ssim_floor=ssim_floor,
                             threads=DEFAULT_THREADS if args.threads is None else args.threads)
    print(f"wrote {args.out} (SSIM {record['ssim']:.3f}, L-inf {record['linf']:.3f}, {record['seconds']:.0f} s) "
          f"and {Path(args.out).with_suffix('.json')}")
    return 0


def _cmd_attack_eval(args: argparse.Namespace) -> int:
    from avsim.experiments.attacks.disappearance import drive_by_frames
    from avsim.experiments.attacks.drive_by_report import plot_confidence_by_detector
    from avsim.experiments.attacks.texture_eval import evaluate_texture, fig3_grid
    from avsim.experiments.attacks.texture_eval_report import write_attack_report
    from avsim.experiments.attacks.eval_set_values import ATTACK_EVAL_SET
    from avsim.experiments.set_overrides import set_flags
    from avsim.config import with_overrides
    from avsim.world.scene import resolve_sign_texture
    from avsim.world.textures import TEXTURE_DIR, load_texture_png

    signs, detectors, placements = args.signs, args.detectors, tuple(args.placements)  # name lists (name_list_flag)
    if len(detectors) > 1 and not args.drives:
        raise ConfigError(f"--detectors {','.join(detectors)}: only the drive-bys use the detectors after the first "
                          f"(the fixed-distance tables use {detectors[0]}), and --drives 0 runs none; give --drives N "
                          "or one detector")
    textures: dict[Path, str] = {}
    for sign in signs:  # every texture decoded, as a scene will decode it, before the first is measured
        texture = resolve_sign_texture(sign)
        load_texture_png(texture, expected_aspect=1.0)
        if texture.resolve() in textures:  # `clean` and `stop_sign`, or a name and its path
            raise ConfigError(f"--signs names one texture twice ({textures[texture.resolve()]} and {sign}, both "
                              f"{texture}); give each once")
        textures[texture.resolve()] = sign
    from avsim.world.towns import PLACEMENTS, TOWNS

    # Every name of the plan is checked before the first render.
    TOWNS.get(args.town)
    for placement in (*placements, args.drive_placement):
        PLACEMENTS.get(placement)
    setting = SETTINGS[args.setting]
    overrides = parse_set(args.set)
    ATTACK_EVAL_SET.check(overrides, (setting,))
    base = setting.config(overrides)
    if args.weights:
        if "detector" not in detectors:
            raise ConfigError("--weights sets the own detector's weights; add detector to --detectors, or drop --weights")
        from avsim.perception.detector.weights import load_weights

        load_weights(args.weights)  # missing, corrupt or mismatched weights fail before anything is rendered
        base = with_overrides(base, {"perception": {"weights_path": args.weights}})
    threshold = base.policy.conf_threshold
    from avsim.sensors.gl import check_offscreen_rendering

    check_offscreen_rendering()  # no EGL: one line before the folder is made, not after "measuring ..."
    out = Path(args.out)
    reports, drive_bys = [], {}
    with locked_output(out, f"avsim attack eval --out {out}"):  # one writer at a time; a failed start leaves no folder
        for sign in signs:
            print(f"measuring {sign} ...", flush=True)
            reports.append(evaluate_texture(sign, args.town, placements, threshold, base=base, detector=detectors[0]))
            for detector in detectors if args.drives else ():
                drive_bys[sign, detector] = drive_by_frames(sign, detector, args.town, args.drive_placement, args.drives,
                                                            base=base)
        fig3 = fig3_grid(signs, out / "fig3_front_30m.png", town=args.town, base=base, detector=detectors[0])
        figure = plot_confidence_by_detector(drive_bys, out / "confidence_by_detector.png") if drive_bys else None
        path = write_attack_report(reports, args.town, threshold, TEXTURE_DIR, out, fig3, drive_bys, figure,
                                   setting=setting, perception=detectors[0], weights=args.weights,
                                   set_flags=set_flags(overrides))
    print(path.read_text())
    print(f"wrote {path}")
    return 0


def _cmd_attack_sweep(args: argparse.Namespace) -> int:
    from avsim.experiments.attacks.budget_sweep import BUDGET_KEY, budget_sweep
    from avsim.experiments.recordings import DEFAULT_MCAP, DEFAULT_RRD

    if args.method not in BUDGET_KEY:
        raise ConfigError(f"unknown attack '{args.method}'; choose one of: {', '.join(sorted(BUDGET_KEY))}")
    budgets = [float(b) for b in args.budgets]  # each in (0, 1] (number_list_flag)
    if not args.closed_loop and (args.rrd_mode, args.mcap_mode) != (None, None):
        raise ConfigError("--rrd and --mcap choose which closed-loop runs are recorded; add --closed-loop FILE, "
                          "or drop them")
    rrd, mcap = args.rrd_mode or DEFAULT_RRD, args.mcap_mode or DEFAULT_MCAP
    protocol = None
    if args.closed_loop:
        from avsim.experiments.attacks.budget_success import load_protocol

        protocol = load_protocol(args.closed_loop)  # checked before any texture is optimised
    with locked_output(args.out, f"avsim attack sweep --out {args.out}"):  # one writer at a time
        csv_path, plot_path = budget_sweep(args.method, budgets, Path(args.out), args.steps, args.seed, args.weights,
                                           protocol=protocol, workers=args.workers, rrd=rrd, mcap=mcap)
    print(f"wrote {csv_path} and {plot_path}")
    return 0


def add_commands(sub) -> None:
    """Add `avsim attack generate | eval | sweep` to the subcommands `sub`."""
    attack = sub.add_parser("attack", help="optimise adversarial stop-sign textures and measure them in renders")
    asub = attack.add_subparsers(dest="attack_command", required=True)
    gen = asub.add_parser("generate", help="optimise one texture against a detector (or remake one with --from)")
    gen.add_argument("--method", help="chen, eykholt, lu_v2, lu_v3, yang, driveby or range_inflation")
    add_output_argument(gen, "--out", kind=FILE, suffix=".png", companions=(".json",), required=True,
                        help="PNG to write (a JSON record is written beside it)")
    add_input_argument(gen, "--from", dest="from_json", metavar="JSON",
                     help="regenerate the texture a record describes (e.g. textures/driveby_detector.json): the same "
                          "method, hyperparameters, seed, detector, view bank and budget")
    gen.add_argument("--detector", help="the detector the texture is optimised against: detector (avsim's own, the "
                                        "default), coco (the COCO CenterNet port), yolo (YOLOv3-tiny), ensemble (detector "
                                        "and coco at once), ensemble_all (all three at once) or ensemble_all_2of3 (all three, "
                                        "scored as the 2-of-3 vote reports: the second-highest)")
    gen.add_argument("--seed", type=SEED_FLAG)
    gen.add_argument("--steps", type=STEPS_FLAG, help="optimisation steps (default: the method's)")
    gen.add_argument("--views-per-step", type=number_flag(1, 1000, integer=True), help="EOT views per step (default: the method's)")
    add_input_argument(gen, "--weights", default="", help="detector weights (default: the shipped ones)")
    gen.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="a method hyperparameter, e.g. --set eps=0.1 (repeatable)")
    gen.add_argument("--cameras", type=name_list_flag(),
                     help="comma-separated cameras whose views the texture is optimised over: front, side "
                          "(default front; front,side is the adaptive attacker against the side-camera defence)")
    gen.add_argument("--ssim-floor", type=number_flag(0, 1, lo_open=True, hi_open=True),
                     help="camouflage budget: the saved PNG keeps at least this SSIM to the clean sign on its face "
                          "(default: the method's ssim_floor hyperparameter if it has one, else 0.7); the change is "
                          "scaled back until it does")
    gen.add_argument("--purify", help="attack through the input purification defence: jpeg or median, at the "
                                      "perception defaults (quality 75, 3 px kernel), by BPDA: the purifier runs "
                                      "in the forward pass and is the identity in the backward pass (default none)")
    gen.add_argument("--speed-kmh", type=config_flag(ScenarioConfig, "speed_kmh"),
                     help=f"the attacked speed: the drive-by methods' frames are this speed x 0.05 s apart "
                          f"(default {DEFAULT_ATTACKED_SPEED_KMH:g})")
    gen.add_argument("--threads", type=number_flag(1, 64, integer=True), metavar="N",
                     help=f"torch threads (default {DEFAULT_THREADS}; recorded, since the texture's last bits depend on it)")
    gen.set_defaults(func=_cmd_attack_generate)
    ev = asub.add_parser("eval", help="measure textures in MuJoCo renders; writes report.md and figures")
    ev.add_argument("--signs", type=name_list_flag(), default=["clean", "chen", "eykholt", "lu_v2", "lu_v3", "yang"],
                    help="comma-separated --sign values (default clean,chen,eykholt,lu_v2,lu_v3,yang)")
    ev.add_argument("--town", default="town07")
    ev.add_argument("--placements", type=name_list_flag(), default=["near", "standard", "far"],
                    help="comma-separated placements of the fixed-distance tables, under the first of --detectors "
                         "(default near,standard,far)")
    ev.add_argument("--detectors", type=name_list_flag(EVAL_DETECTORS), default=["detector"],
                    help="comma-separated perceptions the drive-bys are measured under: detector, coco, yolo, "
                         "nanodet (default detector)")
    ev.add_argument("--drives", type=number_flag(0, 10_000, integer=True), default=6,
                    help="drive-bys per texture and detector for the per-frame metrics (default 6: about 280 frames; "
                         "0 skips them)")
    ev.add_argument("--drive-placement", default="standard", help="placement of the drive-bys (default standard)")
    ev.add_argument("--setting", choices=tuple(SETTINGS), default="baseline", metavar="NAME",
                    help="render setting of every frame, one of avsim realism's (docs/realism.md): "
                         f"{', '.join(SETTINGS)} (default baseline, the default renders)")
    ev.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a camera, scenario or perception value under every frame (repeatable), e.g. "
                         "scenario.fog_end_m=300; keys the evaluation sets itself are refused (docs/attacks.md)")
    add_input_argument(ev, "--weights", default="",
                       help="the own detector's weights for --detectors detector (default: the shipped "
                            "models/sign_detector.pt), e.g. models/sign_detector_scenes.pt, retrained on the full scene")
    add_output_argument(ev, "--out", kind=FOLDER, default="results/attack_eval", help="report directory")
    ev.set_defaults(func=_cmd_attack_eval)
    sw = asub.add_parser("sweep", help="attack strength against camouflage over a range of budgets")
    sw.add_argument("--method", required=True)
    sw.add_argument("--budgets", required=True, type=number_list_flag(0, 1, lo_open=True),
                    help="comma-separated budgets (eps, eps_peak or sticker area fraction), each in (0, 1]")
    sw.add_argument("--steps", type=STEPS_FLAG, default=100, help="optimisation steps per budget")
    sw.add_argument("--seed", type=SEED_FLAG, default=0)
    add_input_argument(sw, "--weights", default="")
    add_input_argument(sw, "--closed-loop", metavar="FILE",
                    help="also drive past every texture and the clean sign under this attack-success experiment "
                         "file's \"clean\" cell and seeds (e.g. experiments/attacks/success_town07.toml), and report "
                         "the success rate (Wilson 95%%), overrun and braking delay per budget")
    sw.add_argument("--workers", type=number_flag(1, 64, integer=True), default=1, metavar="N",
                    help="closed-loop runs at once (default 1)")
    add_output_argument(sw, "--out", kind=FOLDER, default="results/attack_sweep", help="results directory")
    add_recording_modes(sw, "with --closed-loop: ")
    # None: not given, so that a recording flag without --closed-loop is refused rather than ignored.
    sw.set_defaults(func=_cmd_attack_sweep, rrd_mode=None, mcap_mode=None)
