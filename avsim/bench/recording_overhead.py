"""What recording adds to a run: `avsim bench --recording` prints wall time and file size per recorder.

    print_recording_overhead(repeats=3)

One closed-loop run (Town07 standard, the learned detector, seed 0, one camera: the issue's
baseline) is run plain, with `--rrd`, with `--mcap` and with both, `repeats` times each,
interleaved so that a change in the machine's load hits every variant alike. Each row is the
median wall time, what it adds to the plain run's median, and the file's size in total and
per simulated second. Runs are deterministic, so every repeat writes the same content.
"""

from __future__ import annotations

import importlib.util
import statistics
import tempfile
import time
from pathlib import Path

from avsim.config import SimConfig, with_overrides
from avsim.runner import run_recorded

BASELINE = {"scenario": {"town": "town07", "placement": "standard", "seed": 0}, "perception": {"kind": "detector"}}
VARIANTS = {"plain": (), "rrd": ("rrd",), "mcap": ("mcap",), "rrd + mcap": ("rrd", "mcap")}


def measure(config: SimConfig, repeats: int, variants: dict[str, tuple[str, ...]]) -> dict[str, dict[str, float]]:
    """variant -> {"wall_s", "cpu_s": medians [s], "sim_s": simulated time [s], "<kind>_bytes": file size}."""
    walls: dict[str, list[float]] = {name: [] for name in variants}
    cpus: dict[str, list[float]] = {name: [] for name in variants}
    sizes: dict[str, dict[str, int]] = {name: {} for name in variants}
    sim_s = 0.0
    run_recorded(config)  # the first run in a process builds the network and the GL context
    with tempfile.TemporaryDirectory(prefix="avsim-overhead-") as tmp:
        for _ in range(repeats):
            for name, kinds in variants.items():
                paths = {f"{kind}_path": Path(tmp) / f"run.{kind}" for kind in kinds}
                start, start_cpu = time.perf_counter(), time.process_time()
                output = run_recorded(config, **paths)
                walls[name].append(time.perf_counter() - start)
                cpus[name].append(time.process_time() - start_cpu)
                sim_s = output.result.sim_time_s
                sizes[name] = {f"{kind}_bytes": paths[f"{kind}_path"].stat().st_size for kind in kinds}
    return {name: {"wall_s": statistics.median(walls[name]), "cpu_s": statistics.median(cpus[name]), "sim_s": sim_s,
                   **sizes[name]} for name in variants}


def print_recording_overhead(repeats: int = 3) -> None:
    """Measure the baseline run under each recorder and print one row per variant."""
    variants = dict(VARIANTS)
    if importlib.util.find_spec("rosbags") is None:
        print("(--mcap rows skipped: avsim[ros] is not installed)")
        variants = {name: kinds for name, kinds in variants.items() if "mcap" not in kinds}
    config = with_overrides(SimConfig(), BASELINE)
    rows = measure(config, repeats, variants)
    plain = rows["plain"]
    print(f"Recording overhead: Town07 standard, detector, seed 0, {rows['plain']['sim_s']:.2f} s simulated; "
          f"median of {repeats} interleaved runs each")
    print(f"{'variant':<12} {'wall [s]':>9} {'added':>7} {'CPU [s]':>8} {'added':>7} {'rrd [MB]':>9} {'mcap [MB]':>10} "
          f"{'MB per sim s':>13}")
    for name, row in rows.items():
        total_mb = (row.get("rrd_bytes", 0) + row.get("mcap_bytes", 0)) / 1e6
        cells = [f"{row['rrd_bytes'] / 1e6:.2f}" if "rrd_bytes" in row else "-",
                 f"{row['mcap_bytes'] / 1e6:.2f}" if "mcap_bytes" in row else "-"]
        added_wall, added_cpu = ((row[k] / plain[k] - 1) * 100 for k in ("wall_s", "cpu_s"))
        print(f"{name:<12} {row['wall_s']:>9.2f} {added_wall:>+6.0f}% {row['cpu_s']:>8.2f} {added_cpu:>+6.0f}% {cells[0]:>9} "
              f"{cells[1]:>10} {total_mb / row['sim_s']:>13.2f}")
