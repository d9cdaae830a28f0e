"""What sharing sibling runs' frames saves (`avsim.frame_sharing`): the runs of one place and seed, in
one lock-step batch, first with every car rendering its own frames and then with siblings sharing
theirs; the CPU time of each, and whether every run's result and records are the same.

    MUJOCO_GL=egl python experiments/probes/frame_sharing.py --condition clean --seed 0       # a leaderboard's defences
    MUJOCO_GL=egl python experiments/probes/frame_sharing.py --experiment experiments/coco_detector.toml --cells "Town10 standard"
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

from avsim.experiments.leaderboard import load_leaderboard
from avsim.experiments.spec import load_experiment
from avsim.frame_sharing import sibling_key
from avsim.lockstep import run_lockstep


def _leaderboard_runs(args: argparse.Namespace) -> tuple[list[str], list]:
    board = load_leaderboard(yes=True)
    runs = [run for run in board.iter_runs() if run.condition == args.condition and run.place == args.place
            and run.seed == args.seed and (not args.defences or run.defence in args.defences.split(","))]
    return [run.defence for run in runs], [run.config for run in runs]


def _experiment_runs(args: argparse.Namespace) -> tuple[list[str], list]:
    runs = [run for run in load_experiment(args.experiment).iter_runs()
            if run.cell_name.startswith(args.cells) and run.seed == args.seed]
    return [run.cell_name for run in runs], [run.config for run in runs]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiment", help="an experiment file (default: the defence leaderboard)")
    parser.add_argument("--cells", default="", help="with --experiment: the cells whose names start so")
    parser.add_argument("--condition", default="clean", help="leaderboard: clean, strongest or adaptive")
    parser.add_argument("--place", default="town07 standard", help="leaderboard: the place")
    parser.add_argument("--defences", default="", help="leaderboard: comma-separated names (default: every defence)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    names, configs = _experiment_runs(args) if args.experiment else _leaderboard_runs(args)
    families = Counter(sibling_key(config) for config in configs)
    print(f"{len(configs)} runs ({', '.join(names)}); sibling families: {sorted(families.values(), reverse=True)}")
    timings, outputs = {}, {}
    for share in (False, True):
        started = time.process_time()
        outputs[share] = run_lockstep(configs, share_frames=share)
        timings[share] = time.process_time() - started
    same = all(not isinstance(a, Exception) and a.result == b.result and a.records == b.records
               for a, b in zip(outputs[False], outputs[True]))
    print(f"CPU s: every car its own frames {timings[False]:.1f}, siblings sharing {timings[True]:.1f} "
          f"({timings[False] / timings[True]:.2f}x); every result and record the same: {same}")


if __name__ == "__main__":
    main()
