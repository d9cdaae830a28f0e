"""One closed-loop run with its optional recorders: what `avsim run` and every batch execute.

    output = run_recorded(config, rrd_path="run.rrd", mp4_path=None)
    output.result        # RunResult, as written by `avsim run --json`
    output.records       # one StepRecord per control step (state at sensing time)
    result, wall_s = run_config(config)   # the same run, no recorders

Recording never changes the run: the recorders only read the loop after each step. Each
file appears only when the run completes (the recorders write to a temporary name and
rename on close), so an interrupted run leaves no half-written `.rrd` or `.mp4`.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

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
                 mp4_path: str | os.PathLike | None = None) -> RunOutput:
    """Run `config` to the end, recording it to `rrd_path` (rerun) and `mp4_path` (video) if given."""
    check_meaningful(config)  # a scenario that cannot mean what it says never runs
    start = time.perf_counter()
    loop = ClosedLoop(config)
    try:
        with contextlib.ExitStack() as recorders:
            result = loop.run(on_step=attach_recorders(loop, recorders, rrd_path=rrd_path, mp4_path=mp4_path))
    finally:
        loop.close()
    return RunOutput(result, tuple(loop.records), time.perf_counter() - start)


def attach_recorders(loop: ClosedLoop, stack: contextlib.ExitStack, *, rrd_path: str | os.PathLike | None = None,
                     mp4_path: str | os.PathLike | None = None) -> Callable[[ClosedLoop, StepRecord], None] | None:
    """Open the asked-for recorders of `loop` on `stack` (each writes its file when the stack closes
    without an error); returns the per-step hook that feeds them, or None when none is asked for."""
    hooks = []
    if rrd_path:
        from avsim.recording.rerun_log import RunRecorder

        hooks.append(stack.enter_context(RunRecorder(loop, rrd_path)).on_step)
    if mp4_path:
        from avsim.recording.video import VideoRecorder

        hooks.append(stack.enter_context(VideoRecorder(loop, mp4_path)).on_step)
    if not hooks:
        return None

    def on_step(loop_: ClosedLoop, record: StepRecord) -> None:
        for hook in hooks:
            hook(loop_, record)

    return on_step


def run_config(config: SimConfig) -> tuple[RunResult, float]:
    """Run `config` to the end without recorders; returns the result and the wall-clock time [s]."""
    output = run_recorded(config)
    return output.result, output.wall_s
