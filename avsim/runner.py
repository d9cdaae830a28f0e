"""One closed-loop run with its optional recorders: what `avsim run` and every batch execute.

    output = run_recorded(config, rrd_path="run.rrd", mp4_path=None, mcap_path=None)
    output.result        # RunResult, as written by `avsim run --json`
    output.records       # one StepRecord per control step (state at sensing time)
    result, wall_s = run_config(config)   # the same run, no recorders

Recording never changes the run: the recorders only read the loop after each step. Each
file appears only when the run completes (the recorders write to a temporary name and
rename on close), so an interrupted run leaves no half-written `.rrd`, `.mp4` or `.mcap`.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from avsim.config import SimConfig
from avsim.loop import ClosedLoop
from avsim.metrics import RunResult, StepRecord
from avsim.plausibility import check_meaningful


@dataclass(frozen=True)
class RunOutput:
    """A finished run: its result, its per-step records and the wall-clock time it took [s]."""

    result: RunResult
    records: tuple[StepRecord, ...]
    wall_s: float


def run_recorded(config: SimConfig, *, rrd_path: str | os.PathLike | None = None,
                 mp4_path: str | os.PathLike | None = None, mcap_path: str | os.PathLike | None = None,
                 mcap_images: str = "png",
                 keep_if: Mapping[str, Callable[[RunResult], bool]] | None = None) -> RunOutput:
    """Run `config` to the end, recording it to `rrd_path` (rerun), `mp4_path` (video) and
    `mcap_path` (a ROS 2 bag, needs avsim[ros]; images as `mcap_images`, png or jpeg) where given.

    keep_if: recording kind ("rrd", "mp4", "mcap") -> a test of the run's result; a recording
    whose test fails is discarded when the run ends (its temporary file deleted, nothing written).
    """
    check_meaningful(config)  # a scenario that cannot mean what it says never runs
    start = time.perf_counter()
    loop = ClosedLoop(config)
    try:
        with contextlib.ExitStack() as stack:
            recorders = open_recorders(loop, stack, rrd_path=rrd_path, mp4_path=mp4_path, mcap_path=mcap_path,
                                       mcap_images=mcap_images)
            result = loop.run(on_step=step_hook(recorders))
            finish_recorders(recorders, result, keep_if)
    finally:
        loop.close()
    return RunOutput(result, tuple(loop.records), time.perf_counter() - start)


def open_recorders(loop: ClosedLoop, stack: contextlib.ExitStack, *, rrd_path: str | os.PathLike | None = None,
                   mp4_path: str | os.PathLike | None = None, mcap_path: str | os.PathLike | None = None,
                   mcap_images: str = "png") -> dict[str, Any]:
    """Open the asked-for recorders of `loop` on `stack` (each writes its file when the stack closes
    without an error, unless `finish_recorders` discarded it); returns kind -> recorder."""
    recorders: dict[str, Any] = {}
    if rrd_path:
        from avsim.recording.rerun_log import RunRecorder

        recorders["rrd"] = stack.enter_context(RunRecorder(loop, rrd_path))
    if mp4_path:
        from avsim.recording.video import VideoRecorder

        recorders["mp4"] = stack.enter_context(VideoRecorder(loop, mp4_path))
    if mcap_path:
        from avsim.recording.ros_bag import BagRecorder

        recorders["mcap"] = stack.enter_context(BagRecorder(loop, mcap_path, image_format=mcap_images))
    return recorders


def step_hook(recorders: Mapping[str, Any]) -> Callable[[ClosedLoop, StepRecord], None] | None:
    """The per-step hook that feeds `recorders`, or None when there are none."""
    if not recorders:
        return None

    def on_step(loop_: ClosedLoop, record: StepRecord) -> None:
        for recorder in recorders.values():
            recorder.on_step(loop_, record)

    return on_step


def finish_recorders(recorders: Mapping[str, Any], result: RunResult,
                     keep_if: Mapping[str, Callable[[RunResult], bool]] | None = None) -> None:
    """The run is over: give the bag its result, and discard each recording whose `keep_if` test
    the result fails (then closing the stack writes nothing for it)."""
    if "mcap" in recorders:
        recorders["mcap"].set_result(result)  # the bag's last message: the run's config and result
    for kind, keep in (keep_if or {}).items():
        if kind in recorders and not keep(result):
            recorders[kind].abort()


def run_config(config: SimConfig) -> tuple[RunResult, float]:
    """Run `config` to the end without recorders; returns the result and the wall-clock time [s]."""
    output = run_recorded(config)
    return output.result, output.wall_s
