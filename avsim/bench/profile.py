"""`avsim bench --profile`: where one run's time and one batch of runs' time go on this machine,
and issue 25's speed targets beside what was measured.

Prints measured figures only; nothing asserts. A run's speed is given in wall time (simulated
seconds per wall second: real time) and in this process's CPU time (simulated seconds per CPU
second), which other work on the machine disturbs far less; on a quiet machine with one renderer
thread (LP_NUM_THREADS=1, what each of two workers gets on two cores) the two agree. The targets
are compared with the CPU figure. Compare ratios within one printout, not with another machine's.
"""

from __future__ import annotations

import os
import pickle
import resource
import tempfile
import time
from pathlib import Path

from avsim.config import SimConfig, with_overrides
from avsim.perception.cpu_bf16 import arithmetics_here, auto_arithmetic
from avsim.profiling import STAGES, profile_run

# Issue 25's targets for one run at 1 thread, as real-time ratios.
ONE_RUN_TARGETS = {"town07, one camera": 5.0, "town10, one camera": 3.0, "town07, two cameras": 3.0}


def _config(town: str, policy: str, perception: str, precision: str) -> SimConfig:
    """The study's run in `town` under `policy`, with `perception` ("detector" or "coco") at `precision`."""
    return with_overrides(SimConfig(), {"scenario": {"town": town}, "policy": {"name": policy},
                                        "perception": {"kind": perception, f"{perception}_precision": precision}})


def _print_stages(label: str, config: SimConfig, rrd: bool = False) -> float:
    """Profile one run, print its stage table; returns its simulated seconds per CPU second."""
    with tempfile.TemporaryDirectory() as folder:
        rrd_path = str(Path(folder) / "run.rrd") if rrd else None
        profile = profile_run(config, rrd_path=rrd_path)
        size = f", {os.path.getsize(rrd_path) / 1e6:.1f} MB .rrd" if rrd_path else ""
    sim_s = profile.result.sim_time_s
    print(f"\n  {label}: {sim_s:.1f} s simulated in {profile.wall_s:.1f} s wall = {sim_s / profile.wall_s:.2f}x real time, "
          f"in {profile.cpu_s:.1f} s CPU = {sim_s / profile.cpu_s:.2f}x per CPU second ({profile.steps} control steps{size})")
    print(f"    {'stage':34s} {'wall s':>7s} {'CPU s':>7s} {'CPU share':>9s} {'CPU ms/step':>11s}")
    for stage in (*STAGES, "setup (building the run)", "other"):
        if stage in profile.stage_cpu_s:
            cpu_s = profile.stage_cpu_s[stage]
            print(f"    {stage:34s} {profile.stage_wall_s[stage]:7.2f} {cpu_s:7.2f} {100 * cpu_s / profile.cpu_s:8.1f}% "
                  f"{1e3 * cpu_s / max(1, profile.steps):11.2f}")
    return sim_s / profile.cpu_s


def _cpu_s() -> float:
    """CPU time [s] of this process and of its finished child processes (the pool's workers)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _batch_rate(configs: list[SimConfig], workers: int, batch: int) -> tuple[float, float, float, int]:
    """(simulated seconds per wall second per worker, per CPU second, wall time [s], bytes of records
    sent back) of `configs` run as one local batch."""
    from avsim.experiments.batch import run_batch
    from avsim.experiments.run_task import RunSpec

    specs = [RunSpec("bench", f"run{i}", config.scenario.seed, config) for i, config in enumerate(configs)]
    started, cpu_started = time.perf_counter(), _cpu_s()
    records = run_batch(specs, workers=workers, progress=False, batch=batch)
    wall_s, cpu_s = time.perf_counter() - started, _cpu_s() - cpu_started
    sim_s = sum(r["result"]["sim_time_s"] for r in records if r["status"] == "ok")
    return sim_s / wall_s / workers, sim_s / cpu_s, wall_s, len(pickle.dumps(records))


def _print_batch_row(configs: list[SimConfig], workers: int, batch: int) -> float:
    """Run `configs` as one local batch and print its row of the batch table; returns its simulated
    seconds per CPU second."""
    rate, per_cpu_s, wall_s, sent = _batch_rate(configs, workers, batch)
    print(f"    {workers:7d} {batch:5d} {wall_s:7.1f} {rate:28.2f} {per_cpu_s:16.2f} {sent / 1e3:10.0f} kB")
    return per_cpu_s


def run_profile(quick: bool = False) -> None:
    """Print the stage profiles of single runs, then of a batch, then the targets."""
    print("avsim bench --profile: one run's time by stage (exclusive: a stage excludes those it calls), "
          "then a batch's; 1 torch thread")
    ratios: dict[str, float] = {}
    arithmetics = arithmetics_here()  # bf16 only where this CPU runs it
    for precision in arithmetics:
        ratios[f"town07, one camera, {precision}"] = _print_stages(
            f"town07, baseline (one camera), detector {precision}", _config("town07", "baseline", "detector", precision))
    if not quick:
        for precision in arithmetics:
            ratios[f"town10, one camera, {precision}"] = _print_stages(
                f"town10, baseline (one camera), detector {precision}", _config("town10", "baseline", "detector", precision))
            ratios[f"town07, two cameras, {precision}"] = _print_stages(
                f"town07, side_camera (two cameras), detector {precision}", _config("town07", "side_camera", "detector", precision))
        _print_stages("town07, baseline, detector fp32, recorded (--rrd)", _config("town07", "baseline", "detector", "fp32"), rrd=True)
        ratios["coco"] = _print_stages(f"town07, baseline (one camera), coco {auto_arithmetic()}", _config("town07", "baseline", "coco", "auto"))

    # A batch: the same 8 runs one at a time and 8 to a worker, on one worker and on one per core.
    runs = 4 if quick else 8
    configs = [with_overrides(_config("town07", "baseline", "detector", "auto"), {"scenario": {"seed": seed}})
               for seed in range(runs)]
    print(f"\n  batch of {runs} runs (town07, baseline, detector {auto_arithmetic()}, seeds 0-{runs - 1}):")
    print(f"    {'workers':>7s} {'batch':>5s} {'wall s':>7s} {'sim s per wall s per worker':>28s} "
          f"{'sim s per CPU s':>16s} {'records sent':>13s}")
    per_core: dict[tuple[int, int], float] = {}
    for workers in sorted({1, min(2, os.cpu_count() or 1)}):
        for batch in (1, runs):
            per_core[(workers, batch)] = _print_batch_row(configs, workers, batch)

    # Siblings: a table's policies on the same seeds, which share their frames while they drive alike.
    policies = ("baseline", "adjusted", "side_camera", "combined")
    siblings = [with_overrides(_config("town07", policy, "detector", "auto"), {"scenario": {"seed": seed}})
                for seed in range(runs // len(policies)) for policy in policies]
    print(f"\n  batch of {len(siblings)} sibling runs (town07, {', '.join(policies)}, detector {auto_arithmetic()}, "
          f"seeds 0-{runs // len(policies) - 1}: siblings share their frames while they drive alike), 1 worker:")
    for batch in (1, len(siblings)):
        per_core[("siblings", batch)] = _print_batch_row(siblings, 1, batch)

    print("\n  targets (issue 25) and what this printout measured:")
    for name, target in ONE_RUN_TARGETS.items():
        measured = ", ".join(f"{precision} {ratios[f'{name}, {precision}']:.2f}x" for precision in arithmetics
                             if f"{name}, {precision}" in ratios)
        if measured:
            print(f"    detector closed loop, {name:22s} >= {target:.0f}x real time: {measured} per CPU second")
    if "coco" in ratios:
        print(f"    coco closed loop, one camera           >= 1.5x per core: {ratios['coco']:.2f}x per CPU second, alone")
    gain = per_core[(1, runs)] / per_core[(1, 1)]
    sibling_gain = per_core[("siblings", len(siblings))] / per_core[("siblings", 1)]
    print(f"    batching, sim s per CPU second at N={runs} over N=1 (1 worker) >= 1.5: {gain:.2f} for runs of other seeds, "
          f"{sibling_gain:.2f} for sibling runs")
