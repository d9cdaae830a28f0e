"""Sweep throughput on this machine: runs per minute with 1 and 2 local workers and with Ray.

    python -m avsim.bench.sweep_throughput                   # the smoke sweep's grid at 2 seeds: 8 oracle runs
    python -m avsim.bench.sweep_throughput --seeds 4 --no-ray

Every configuration runs the same specs through `run_batch`, as `avsim sweep` does, timed
from the call to the last record: a pool's process start-up is included. For Ray, the local
cluster's start is timed apart (it is started once per sweep). Prints measured figures only;
nothing asserts.

    runs/min      runs / wall time [1/min]
    scaling       runs/min with 2 workers / (2 x runs/min with 1 worker); 1.0 is perfect. Measured
                  twice: against one worker that renders on every core (what `--workers 1` does),
                  and against one worker on one core's share, which is what each of two workers
                  gets (`run_task.worker_env`): the second is the pool's scaling at a fixed share.
    Ray overhead  Ray's wall time (cluster start included) minus the local pool's, both at 2 workers [s]
    peak memory   highest peak resident set (VmHWM) of a process that ran the runs [MiB]; with 1 local
                  worker the runs share this process, so it includes the driver
    CPU use       CPU time of the processes that ran the runs / wall time [cores]; above 1 per worker
                  when the renderer draws on several threads (Mesa's llvmpipe does)
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from avsim.boundary import run_guarded
from avsim.experiments.batch import run_batch
from avsim.experiments.run_task import RunSpec
from avsim.validation import OneLineArgumentParser, number_flag

SMOKE_SWEEP = Path(__file__).resolve().parents[2] / "experiments" / "sweeps" / "sweep_smoke.toml"
_MIB = 1024 * 1024


@dataclass(frozen=True)
class Timing:
    """One configuration's batch: its wall time [s] and the peak memory of its worker processes [MiB]."""

    label: str
    runs: int
    wall_s: float
    peak_rss_mib: float | None
    cpu_s: float | None  # user + system time of the worker processes [s]
    start_s: float = 0.0  # a Ray cluster's start [s], not in wall_s

    @property
    def runs_per_min(self) -> float:
        """Runs per minute of wall time [1/min]."""
        return 60.0 * self.runs / self.wall_s


def _vm_hwm_mib(pid: int) -> float | None:
    """Peak resident set of a live process [MiB] (Linux /proc), None when gone or unreadable."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024 / _MIB  # kB
    except (OSError, ValueError):
        return None
    return None


class WorkerSampler:
    """Samples the peak resident set and CPU time of this process's descendants that `is_worker` picks
    (by command line).

    A peak (VmHWM) and a CPU time only grow, so sampling every `period_s` misses at most the last
    instants of a worker that exits. Needs psutil (installed with rerun-sdk) to list descendants;
    without it both are None.
    """

    def __init__(self, is_worker: Callable[[list[str]], bool], period_s: float = 0.25) -> None:
        self.is_worker, self.period_s = is_worker, period_s
        self.peaks: dict[int, float] = {}  # pid -> VmHWM [MiB]
        self.cpu: dict[int, float] = {}  # pid -> user + system [s]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def __enter__(self) -> WorkerSampler:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    @property
    def peak_mib(self) -> float | None:
        """The largest peak resident memory of any sampled worker [MiB] (None if none was seen)."""
        return max(self.peaks.values()) if self.peaks else None

    @property
    def cpu_s(self) -> float | None:
        """CPU time of the sampled workers, summed [s] (None if none was seen)."""
        return sum(self.cpu.values()) if self.cpu else None

    def _sample(self) -> None:
        try:
            import psutil
        except ImportError:
            return
        me = psutil.Process()
        while not self._stop.wait(self.period_s):
            for child in me.children(recursive=True):
                try:
                    if not self.is_worker(child.cmdline()):
                        continue
                    times = child.cpu_times()
                except psutil.Error:  # exited meanwhile
                    continue
                self.cpu[child.pid] = times.user + times.system
                peak = _vm_hwm_mib(child.pid)
                if peak is not None:
                    self.peaks[child.pid] = max(peak, self.peaks.get(child.pid, 0.0))


def _is_pool_worker(cmdline: list[str]) -> bool:
    return any("spawn_main" in part for part in cmdline)


def _is_ray_worker(cmdline: list[str]) -> bool:
    # Ray titles a worker by its task (ray::execute) or ray::IDLE; its agents are ray::DashboardAgent etc.
    return bool(cmdline) and (cmdline[0] == "ray::IDLE" or cmdline[0].startswith("ray::execute"))


def time_local(specs: Sequence[RunSpec], workers: int) -> Timing:
    """Run `specs` through `run_batch` on a local pool of `workers` processes, timed."""
    own_before = resource.getrusage(resource.RUSAGE_SELF)
    with WorkerSampler(_is_pool_worker) as sampler:
        start = time.perf_counter()
        run_batch(specs, workers=workers, progress=False)
        wall_s = time.perf_counter() - start
    if workers == 1:  # the runs ran in this process
        own = resource.getrusage(resource.RUSAGE_SELF)
        peak, cpu_s = _vm_hwm_mib(os.getpid()), own.ru_utime + own.ru_stime - own_before.ru_utime - own_before.ru_stime
    else:
        peak, cpu_s = sampler.peak_mib, sampler.cpu_s
    return Timing(f"local, {workers} worker{'s' if workers != 1 else ''}", len(specs), wall_s, peak, cpu_s)


def time_one_core(specs: Sequence[RunSpec]) -> Timing:
    """The specs in one spawned worker given one core's share, as each of two workers gets on
    two cores (`run_task.worker_env`): the baseline for scaling at a fixed share per worker."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from avsim.workers import init_worker

    context = multiprocessing.get_context("spawn")
    with WorkerSampler(_is_pool_worker) as sampler:
        start = time.perf_counter()
        with ProcessPoolExecutor(1, mp_context=context, initializer=init_worker,
                                 initargs=({"LP_NUM_THREADS": "1"}, os.getpid())) as pool:
            pool.submit(run_batch, list(specs), workers=1, progress=False).result()
        wall_s = time.perf_counter() - start
    return Timing("local, 1 worker on 1 core", len(specs), wall_s, sampler.peak_mib, sampler.cpu_s)


def time_ray(specs: Sequence[RunSpec], workers: int) -> Timing:
    """Run `specs` as Ray tasks on a local cluster of `workers` CPUs, timed (the cluster's start apart)."""
    from avsim.experiments.ray_backend import session

    start = time.perf_counter()
    with session(None, workers):
        start_s = time.perf_counter() - start
        with WorkerSampler(_is_ray_worker) as sampler:
            start = time.perf_counter()
            run_batch(specs, workers=workers, progress=False, backend="ray")
            wall_s = time.perf_counter() - start
    return Timing(f"ray, local cluster of {workers} CPUs", len(specs), wall_s, sampler.peak_mib, sampler.cpu_s, start_s)


def bench_specs(seeds: int) -> list[RunSpec]:
    """The smoke sweep's grid (2 speeds x 2 policies, oracle perception, 60 m approach) at `seeds` seeds."""
    from avsim.experiments.sweep import load_sweep

    return dataclasses.replace(load_sweep(SMOKE_SWEEP), seeds=seeds).specs()


PROG = "python -m avsim.bench.sweep_throughput"


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m avsim.bench.sweep_throughput`: print sweep throughput; returns the exit status."""
    parser = OneLineArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=number_flag(1, 1000, integer=True), default=2,
                        help="seeds per grid point of the smoke sweep (4 runs each)")
    parser.add_argument("--no-ray", action="store_true", help="only the local pool")
    args = parser.parse_args(argv)
    return run_guarded(lambda: _bench(args), prog=PROG)


def _bench(args: argparse.Namespace) -> int:

    specs = bench_specs(args.seeds)
    print(f"sweep throughput: {len(specs)} runs ({SMOKE_SWEEP.name} grid x {args.seeds} seeds, oracle perception)")
    # One worker first: its peak is this process's, before the other configurations run.
    timings = [time_local(specs, 1), time_local(specs, 2), time_one_core(specs)]
    if not args.no_ray:
        timings.append(time_ray(specs, 2))
    for t in timings:
        peak = "n/a" if t.peak_rss_mib is None else f"{t.peak_rss_mib:.0f} MiB"
        cores = "n/a" if t.cpu_s is None else f"{t.cpu_s / t.wall_s:.2f}"
        start = f" (+ {t.start_s:.1f} s cluster start)" if t.start_s else ""
        print(f"  {t.label:28s} {t.runs_per_min:6.1f} runs/min   {t.wall_s:6.1f} s{start:24s} "
              f"CPU use {cores} cores   peak memory per worker {peak}")
    one, two, one_core = timings[0], timings[1], timings[2]
    print(f"  scaling 1 -> 2 workers       {two.runs_per_min / (2 * one.runs_per_min):6.2f}        "
          f"(speed-up {two.runs_per_min / one.runs_per_min:.2f}x; the lone worker renders on both cores)")
    print(f"  scaling, one core per worker {two.runs_per_min / (2 * one_core.runs_per_min):6.2f}        "
          f"(speed-up {two.runs_per_min / one_core.runs_per_min:.2f}x over one worker on one core)")
    if not args.no_ray:
        ray = timings[3]
        extra_s = ray.start_s + ray.wall_s - two.wall_s
        print(f"  Ray overhead vs local pool   {extra_s:+6.1f} s      ({100 * extra_s / two.wall_s:+.0f}% of the pool's "
              f"{two.wall_s:.1f} s; {extra_s / ray.runs:+.2f} s per run)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
