"""Many closed-loop runs in one process, stepped in lock-step: one network call per control tick
over every car's camera frames.

    outputs = run_lockstep([config_a, config_b, ...], recordings=[{}, {"rrd_path": "b.rrd"}, ...])
    outputs[i]    # RunOutput of configs[i], or the exception that ended it

Each tick, every car that is still running renders its cameras (`FramePerception.frame_requests`);
the frames of all cars that share a perception config go through their shared detector at once
(`detect_many`); then each car decides, actuates and steps its physics (`ClosedLoop.step_with`).
A car whose run ends drops out; the others go on. Perceptions that do not run a network on
pixels (the oracle, none) perceive car by car, as in a lone run. Cars that would see the same
frames (runs that differ only in their policy, while they still drive alike) have them rendered
and detected once (`avsim.frame_sharing`).

A run's result does not depend on its batch: the detectors' `detect_many` gives each frame what
a lone `detect` gives it, bit for bit (see `avsim.perception.detector.infer` for why under bf16
frames can share a call and under fp32 they cannot), every car keeps its own MuJoCo model,
data, renderer and seeded sensor noise, and the cars are stepped in a fixed order.
`tests/test_lockstep.py` checks a mixed batch against the same runs alone.

The wall-clock time of a run in a batch is its share of the batch's: each tick's time divided
evenly among the cars that took part in it.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from avsim.config import SimConfig
from avsim.frame_sharing import KeptFramePools, SightKey, sight_key
from avsim.loop import ClosedLoop
from avsim.perception.base import Detection
from avsim.perception.factory import FrameDetectorCache
from avsim.perception.frame import FramePerception, FrameRequest, detect_parts_many, detections_from_parts
from avsim.metrics import RunResult
from avsim.plausibility import check_meaningful
from avsim.runner import RunOutput, finish_recorders, open_recorders, step_hook
from avsim.termination import raise_if_interrupted


class _Car:
    """One run of the batch: its loop, its recorders and their hook, and the wall time charged to it [s]."""

    def __init__(self, loop: ClosedLoop, stack: contextlib.ExitStack, recording: Mapping[str, Any]) -> None:
        self.loop = loop
        self.stack = stack
        self.keep_if: Mapping[str, Callable[[RunResult], bool]] | None = recording.get("keep_if")
        self.recorders = open_recorders(loop, stack, **{k: v for k, v in recording.items() if k != "keep_if"})
        self.on_step = step_hook(self.recorders)
        self.wall_s = 0.0


def run_lockstep(configs: Sequence[SimConfig], *, recordings: Sequence[Mapping[str, Any]] | None = None,
                 share_frames: bool = True) -> list[RunOutput | Exception]:
    """Run every config to the end in lock-step; returns, per config, its `RunOutput` or the
    exception that ended it (a run that fails does not stop the others).

    recordings: per config, `run_recorded`'s recording arguments (rrd_path, mp4_path, mcap_path,
    mcap_images, keep_if), or {} for none.
    share_frames: render and detect once the frames several cars would see (`avsim.frame_sharing`);
    off, every car renders its own (the same results, more time: for measuring what sharing saves).
    """
    recordings = list(recordings) if recordings is not None else [{}] * len(configs)
    if len(recordings) != len(configs):
        raise ValueError(f"need one recording (or {{}}) per config: {len(recordings)} for {len(configs)} configs")
    detectors = FrameDetectorCache()
    pools = KeptFramePools() if share_frames else None
    outputs: list[RunOutput | Exception | None] = [None] * len(configs)
    cars: dict[int, _Car] = {}
    try:
        for index, config in enumerate(configs):
            started = time.perf_counter()
            try:
                car = _start(config, detectors, recordings[index], pools)
            except Exception as exc:  # noqa: BLE001 - this run failed; the batch goes on
                raise_if_interrupted(exc)  # a Ctrl-C a C call wrapped stops the batch
                outputs[index] = exc
                continue
            car.wall_s = time.perf_counter() - started
            cars[index] = car
        while cars:
            started = time.perf_counter()
            running = {index: car for index, car in cars.items() if not car.loop.done()}
            for index in [i for i in cars if i not in running]:
                outputs[index] = _finish(cars.pop(index))
            failed = _tick(running, share_frames)
            share_s = (time.perf_counter() - started) / max(1, len(running))
            for index, car in running.items():
                car.wall_s += share_s
            for index, exc in failed.items():
                _abandon(cars.pop(index))
                outputs[index] = exc
    finally:
        for car in cars.values():  # only left here when something outside a run went wrong
            _abandon(car)
    return [output for output in outputs if output is not None]


def _start(config: SimConfig, detectors: FrameDetectorCache, recording: Mapping[str, Any],
           pools: KeptFramePools | None) -> _Car:
    check_meaningful(config)  # as `run_recorded` does: a scenario that cannot mean what it says never runs
    loop = ClosedLoop(config, detectors)
    if pools is not None:
        pools.join(loop)  # before the recorders open and render the first sensing state
    stack = contextlib.ExitStack()
    try:
        return _Car(loop, stack, recording)
    except BaseException:
        stack.close()
        loop.close()
        raise


def perceive_together(cars: Sequence[tuple[ClosedLoop, tuple[str, ...]]], share_frames: bool = True
                      ) -> list[dict[str, list[Detection]] | Exception]:
    """Perceive each (loop, cameras) at its current state, as `loop.perceive(cameras)` would, with
    one network call per shared detector over all of their frames, and each set of frames that
    several cars would see rendered and detected once (`avsim.frame_sharing`; unless `share_frames`
    is off). Returns, per car, its detections by camera, or the exception its rendering raised."""
    out: list[dict[str, list[Detection]] | Exception] = []
    groups: dict[int, list[tuple[int, FrameRequest]]] = {}
    leaders: dict[SightKey, int] = {}  # sight key -> the car that renders and detects those frames
    followers: dict[int, int] = {}  # car -> its leader, whose detections it takes
    rendered: list[int] = []  # the cars whose own frames are rendered and detected
    for index, (loop, cameras) in enumerate(cars):
        try:
            if isinstance(loop.perception, FramePerception):
                key = sight_key(loop, cameras) if share_frames else None
                leader = leaders.get(key) if key is not None else None
                if leader is not None:
                    if loop.perception.noise is not None:  # the state its own draw would leave
                        loop.perception.noise.follow(cars[leader][0].perception.noise)
                    followers[index] = leader
                else:
                    for request in loop.perception.frame_requests(loop.rig, loop.data, cameras):
                        groups.setdefault(id(loop.perception.detector), []).append((index, request))
                    rendered.append(index)
                    if key is not None:
                        leaders[key] = index
                out.append({})  # its detections by camera, once the networks have run (below)
            else:
                out.append(loop.perceive(cameras))
        except Exception as exc:  # noqa: BLE001 - this car's failure, not the batch's
            raise_if_interrupted(exc)  # a Ctrl-C a C call wrapped stops the batch
            out.append(exc)
    found_by: dict[tuple[int, str], Any] = {}  # (leader, camera) -> what the networks found (`detect_parts_many`)
    for group in groups.values():
        group = [(index, request) for index, request in group if not isinstance(out[index], Exception)]
        if not group:
            continue
        perception = cars[group[0][0]][0].perception
        found = detect_parts_many(perception.detector, [request for _, request in group])
        for (index, (_, camera, _)), frame_parts in zip(group, found):
            found_by[index, camera] = frame_parts
    for index in [*rendered, *followers]:
        loop, cameras = cars[index]
        source = followers.get(index, index)
        out[index] = {camera: loop.perception.keep(detections_from_parts(loop.perception.detector, found_by[source, camera]))
                      for camera in cameras}
    return out


def _tick(cars: dict[int, _Car], share_frames: bool) -> dict[int, Exception]:
    """One control step of every car: render all, one network call per shared detector, then each
    car's decision, actuation and physics. Returns the cars whose run raised, with the exception."""
    indices = list(cars)
    perceived = perceive_together([(cars[i].loop, cars[i].loop.policy.cameras) for i in indices], share_frames)
    failed: dict[int, Exception] = {}
    for index, detections in zip(indices, perceived):
        if isinstance(detections, Exception):
            failed[index] = detections
            continue
        car = cars[index]
        try:
            record = car.loop.step_with(detections)
            if car.on_step is not None:
                car.on_step(car.loop, record)
        except Exception as exc:  # noqa: BLE001
            raise_if_interrupted(exc)  # a Ctrl-C a C call wrapped stops the batch
            failed[index] = exc
    return failed


def _finish(car: _Car) -> RunOutput | Exception:
    """The finished run's output, its recordings written; or the exception that writing raised."""
    loop = car.loop
    try:
        result = loop.result(loop.stopped)
        finish_recorders(car.recorders, result, car.keep_if)
        car.stack.close()
    except Exception as exc:  # noqa: BLE001
        _abandon(car)
        raise_if_interrupted(exc)  # a Ctrl-C a C call wrapped stops the batch
        return exc
    loop.close()
    return RunOutput(result, tuple(loop.records), car.wall_s)


def _abandon(car: _Car) -> None:
    """Close a run that will not finish: its recorders leave no file (they see the exception)."""
    try:
        car.stack.__exit__(RuntimeError, RuntimeError("run abandoned"), None)
    finally:
        car.loop.close()
