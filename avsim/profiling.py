"""Where a closed-loop run's time goes, stage by stage: `avsim bench --profile`.

    timer = StageTimer()
    timer.wrap(loop.rig, "render_rgb", "render and read-back")
    with timer.running():
        loop.run()
    timer.seconds()     # {"render and read-back": 3.1, ...}: exclusive time per stage [s]

The timer wraps callables (an object's method, or a module's function) for the length of a
profile and restores them afterwards; nothing in the loop itself is instrumented, so an unprofiled
run pays nothing. Stages nest: a stage's time excludes the stages called inside it (the network
inside the detector inside the perception), so the stages add up to the wall time with the rest
counted as "other".

Stages of one run (`profile_run`):
    render and read-back          the renderer, and copying the pixels out (`CameraRig`)
    sensor noise                  `SensorNoise.apply`
    detector pre-processing       crop / letterbox to the network's input tensor
    detector network              the convolutions (the own detector's `_maps`)
    detector post-processing      decoding, NMS, boxes back to image pixels
    detector (other kinds)        a COCO, ONNX or ensemble detector's whole call
    policy                        `policy.decide`
    physics: MuJoCo               `mj_step`
    physics: tyre, ABS and TCS    the rest of `Vehicle.advance` (the Python tyre model)
    recording                     the recorders' per-step hooks (`--rrd`)
    setup (building the run)      the scene, model, renderer and networks (`ClosedLoop(config)`)
    other                         the loop's own bookkeeping, records, Python overhead
"""

from __future__ import annotations

import contextlib
import time
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

STAGES = ("render and read-back", "sensor noise", "detector pre-processing", "detector network",
          "detector post-processing", "detector (other kinds)", "policy", "physics: MuJoCo",
          "physics: tyre, ABS and TCS", "recording")


class StageTimer:
    """Exclusive wall and CPU time per named stage, from callables it wraps (module docstring).

    CPU time is this process's (`time.process_time`: every thread, the renderer's included). It
    is what a stage costs whatever else the machine runs; wall time also counts waiting for a core.
    """

    def __init__(self) -> None:
        self._seconds: dict[str, float] = {}
        self._cpu_seconds: dict[str, float] = {}
        self._calls: dict[str, int] = {}
        # per open stage: [wall start, CPU start, wall and CPU time spent in nested stages]
        self._stack: list[list[float]] = []
        self._restore: list[Callable[[], None]] = []

    def wrap(self, owner: Any, name: str, stage: str) -> None:
        """Time every call of `owner.name` (a method of an object, or a module's function) as `stage`."""
        original = getattr(owner, name)

        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append([time.perf_counter(), time.process_time(), 0.0, 0.0])
            try:
                return original(*args, **kwargs)
            finally:
                start, cpu_start, nested, cpu_nested = self._stack.pop()
                elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
                self._seconds[stage] = self._seconds.get(stage, 0.0) + elapsed - nested
                self._cpu_seconds[stage] = self._cpu_seconds.get(stage, 0.0) + cpu - cpu_nested
                self._calls[stage] = self._calls.get(stage, 0) + 1
                if self._stack:
                    self._stack[-1][2] += elapsed
                    self._stack[-1][3] += cpu

        had_own = isinstance(owner, types.ModuleType) or name in vars(owner)
        setattr(owner, name, timed)
        self._restore.append((lambda: setattr(owner, name, original)) if had_own else (lambda: delattr(owner, name)))

    def replace(self, owner: Any, name: str, value: Any) -> None:
        """Set `owner.name` to `value` until the end of `running`."""
        original = getattr(owner, name)
        setattr(owner, name, value)
        self._restore.append(lambda: setattr(owner, name, original))

    @contextlib.contextmanager
    def running(self) -> Iterator[None]:
        """Keep the wrappers for the block; restore every wrapped callable afterwards."""
        try:
            yield
        finally:
            for restore in reversed(self._restore):
                restore()
            self._restore.clear()

    def seconds(self) -> dict[str, float]:
        """Exclusive wall time per stage [s], for the stages that were called."""
        return dict(self._seconds)

    def cpu_seconds(self) -> dict[str, float]:
        """Exclusive CPU time per stage [s], for the stages that were called."""
        return dict(self._cpu_seconds)

    def calls(self) -> dict[str, int]:
        """Calls counted per stage."""
        return dict(self._calls)


class _TimedMujoco(types.ModuleType):
    """`mujoco` as `avsim.vehicle.physics` sees it, with `mj_step` timed as its own stage."""

    def __init__(self, real: types.ModuleType, timer: StageTimer) -> None:
        super().__init__(real.__name__)
        self._real = real
        self.mj_step = real.mj_step
        timer.wrap(self, "mj_step", "physics: MuJoCo")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)


def instrument(timer: StageTimer, loop: Any) -> None:
    """Wrap the stages of one `ClosedLoop` (its renderer, noise, detector, policy and physics)."""
    from avsim.perception.frame import FramePerception
    from avsim.vehicle import physics

    timer.wrap(loop.rig, "render_rgb", "render and read-back")
    timer.wrap(loop.rig, "render_segmentation", "render and read-back")
    timer.wrap(loop.policy, "decide", "policy")
    timer.wrap(loop.vehicle, "advance", "physics: tyre, ABS and TCS")
    if not isinstance(physics.mujoco, _TimedMujoco):
        timer.replace(physics, "mujoco", _TimedMujoco(physics.mujoco, timer))
    perception = loop.perception
    if not isinstance(perception, FramePerception):
        return
    if perception.noise is not None:
        timer.wrap(perception.noise, "apply", "sensor noise")
    detector = perception.detector
    if hasattr(detector, "_maps"):  # the own detector: its three parts
        timer.wrap(detector, "_passes", "detector pre-processing")
        timer.wrap(detector, "_maps", "detector network")
        timer.wrap(detector, "detect_many", "detector post-processing")
    else:
        timer.wrap(detector, "detect", "detector (other kinds)")



@dataclass(frozen=True)
class RunProfile:
    """One profiled run: its result, control steps, and wall and CPU time [s], in all and per stage
    (exclusive; "setup (building the run)" and "other" included, so the stages add up)."""

    result: Any
    steps: int
    wall_s: float
    cpu_s: float
    stage_wall_s: dict[str, float]
    stage_cpu_s: dict[str, float]


def profile_run(config: Any, *, rrd_path: str | None = None) -> RunProfile:
    """Run `config` once with every stage timed (and recorded to `rrd_path` if given). The run's
    result is the unprofiled run's: the wrappers only read the clocks."""
    from avsim.loop import ClosedLoop
    from avsim.runner import open_recorders, step_hook

    timer = StageTimer()
    started, cpu_started = time.perf_counter(), time.process_time()
    loop = ClosedLoop(config)
    setup_s, setup_cpu_s = time.perf_counter() - started, time.process_time() - cpu_started
    try:
        with timer.running(), contextlib.ExitStack() as recorders:
            instrument(timer, loop)
            hook = step_hook(open_recorders(loop, recorders, rrd_path=rrd_path))
            result = loop.run(on_step=None if hook is None else _timed_hook(timer, hook))
    finally:
        loop.close()
    wall_s, cpu_s = time.perf_counter() - started, time.process_time() - cpu_started
    seconds = {"setup (building the run)": setup_s, **timer.seconds()}
    seconds["other"] = max(0.0, wall_s - sum(seconds.values()))
    cpu_seconds = {"setup (building the run)": setup_cpu_s, **timer.cpu_seconds()}
    cpu_seconds["other"] = max(0.0, cpu_s - sum(cpu_seconds.values()))
    return RunProfile(result, len(loop.records), wall_s, cpu_s, seconds, cpu_seconds)


def _timed_hook(timer: StageTimer, hook: Callable[..., None]) -> Callable[..., None]:
    holder = types.SimpleNamespace(hook=hook)
    timer.wrap(holder, "hook", "recording")
    return lambda loop, record: holder.hook(loop, record)
