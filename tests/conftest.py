"""Shared helpers: cached closed-loop runs so several tests can assert on one run."""

from __future__ import annotations

import fcntl
import functools
import os
import resource

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from avsim.runner import run_config  # noqa: E402
from avsim.metrics import RunResult  # noqa: E402
from file_order import longest_files_first  # noqa: E402
from helpers import make_config  # noqa: E402


@functools.lru_cache(maxsize=None)
def _cached_run(town: str, placement: str, policy: str, seed: int, perception: str, sign: str) -> RunResult:
    config = make_config(scenario={"town": town, "placement": placement, "seed": seed, "sign": sign},
                         policy={"name": policy}, perception={"kind": perception})
    return run_config(config)[0]


@pytest.fixture
def study_run():
    """run(town, placement, policy, seed=0, perception="oracle", sign="clean") -> RunResult at 85 km/h,
    cached for the session so several tests can assert on one run."""
    return lambda town, placement, policy, seed=0, perception="oracle", sign="clean": _cached_run(
        town, placement, policy, seed, perception, sign)


@pytest.fixture
def one_local_ray_cluster_at_a_time(tmp_path_factory):
    """Under pytest-xdist, holds a lock shared by the session's workers while the test runs, so that two
    tests never start local Ray clusters at once (they would compete for ports, /tmp/ray and both cores)."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        yield
        return
    lock_path = tmp_path_factory.getbasetemp().parent / "ray-cluster.lock"  # this session's folder, not the worker's
    with lock_path.open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


# ---- The longest files first, for `--dist loadfile` (`file_order.py`) ------------------------------

def pytest_collection_modifyitems(config, items):
    longest_files_first(items)


# ---- `pytest --cpu-durations=N`: where the suite's CPU time goes --------------------------------
# Wall times are meaningless on a shared machine; CPU time is not. Each test phase (setup, call,
# teardown) is charged this process's CPU time (every thread: EGL's llvmpipe, torch, the loop) plus
# that of the child processes it waited for (CLI subprocesses, sweep workers). Ray's daemons are not
# children of the test and go uncounted. Works under pytest-xdist: the figure travels on the report.

def pytest_addoption(parser):
    parser.addoption("--cpu-durations", type=int, default=None, metavar="N",
                     help="print the N tests that used the most CPU time (0: all) and the pass's CPU total")


def _cpu_s() -> float:
    own, children = os.times(), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.user + own.system + children.ru_utime + children.ru_stime


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    started = getattr(item, "_cpu_started_s", None)
    report.cpu_s = None if started is None else _cpu_s() - started
    item._cpu_started_s = _cpu_s()  # the next phase starts here
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item, nextitem):
    item._cpu_started_s = _cpu_s()
    return (yield)


_CPU_BY_TEST: dict[str, list[float]] = {}


def pytest_runtest_logreport(report):
    cpu_s = getattr(report, "cpu_s", None)
    if cpu_s is not None:
        totals = _CPU_BY_TEST.setdefault(report.nodeid, [0.0, 0.0])
        totals[0] += cpu_s
        totals[1] += report.duration


def pytest_terminal_summary(terminalreporter, config):
    top = config.getoption("--cpu-durations")
    if top is None or not _CPU_BY_TEST:
        return
    ranked = sorted(_CPU_BY_TEST.items(), key=lambda item: -item[1][0])
    terminalreporter.section("CPU time per test (setup + call + teardown, own process and waited-for children)")
    for nodeid, (cpu_s, wall_s) in ranked[:top or None]:
        terminalreporter.write_line(f"{cpu_s:8.1f} s CPU {wall_s:8.1f} s wall  {nodeid}")
    cpu_total_s = sum(cpu for cpu, _ in _CPU_BY_TEST.values())
    wall_total_s = sum(wall for _, wall in _CPU_BY_TEST.values())
    terminalreporter.write_line(f"{cpu_total_s:8.1f} s CPU {wall_total_s:8.1f} s wall  in {len(_CPU_BY_TEST)} tests")
