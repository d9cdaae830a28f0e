"""Probe: what one drive-by optimisation step costs against each attack target, in CPU seconds.

One process renders the closed-loop view bank once (as `avsim attack generate --method driveby` does),
then runs the drive-by attack for 2 and for 6 steps against each named target on that bank; the CPU
time of the 4 extra steps over 4 is the cost of a step (setup and the PNG's budget check cancel out).
CPU time, not wall time: the machine may be shared.

    MUJOCO_GL=egl nice -n 5 python experiments/probes/attack_step_cost.py ensemble_all yolo
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import torch

from avsim.attacks.eot import EotScene
from avsim.attacks.generate import default_bank, generate, prepare
from avsim.attacks.targets import TARGET_NAMES, build_target

STEPS = (2, 6)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("targets", nargs="+", choices=TARGET_NAMES)
    parser.add_argument("--threads", type=int, default=2, help="torch threads (generate's default)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    bank_spec, photometric = default_bank("driveby", ("front",), 85.0)
    setup = prepare("", bank_spec, "detector", photometric)
    print(f"view bank: {len(setup.scene.bank)} views, {setup.cpu_seconds:.1f} CPU s to load and render")
    with tempfile.TemporaryDirectory() as out:
        for name in args.targets:
            target = build_target(name)
            scene = EotScene(setup.scene.bank, target, photometric)
            target_setup = dataclasses.replace(setup, scene=scene, detector=name, weight_hashes=target.weight_hashes())
            cpu_s = {}
            for steps in STEPS:
                started = time.process_time()
                generate("driveby", Path(out) / f"{name}_{steps}.png", setup=target_setup,
                         hyperparameters={"steps": steps}, threads=args.threads, progress=False)
                cpu_s[steps] = time.process_time() - started
            per_step = (cpu_s[STEPS[1]] - cpu_s[STEPS[0]]) / (STEPS[1] - STEPS[0])
            print(f"{name}: {per_step:.2f} CPU s a step; 300 steps {per_step * 300 / 60:.1f} CPU min", flush=True)


if __name__ == "__main__":
    main()
