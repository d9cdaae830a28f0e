"""`avsim bench` rows for `avsim/StopSign-v0`: steps per second with and without camera images,
and the environment's cost over `ClosedLoop` doing the same work.

The closed loop runs `baseline` from rest; the environment (made with `gymnasium.make`, its
wrappers included) is then driven with the throttle and brake that run recorded, so both
simulate the same trajectory with the same perception, step for step. Only stepping is timed:
the first closed-loop step (which creates the renderer) and the environment's reset (which
does the same) are left out, and the reset is timed on its own. Each figure is the fastest of
`repeats` runs, since other work on the machine only ever slows a run down.
"""

from __future__ import annotations

import time

import gymnasium

from avsim.config import SimConfig, with_overrides
from avsim.gym import ENV_ID
from avsim.loop import ClosedLoop


def _loop_ms_per_step(config: SimConfig) -> tuple[float, list[tuple[float, float]]]:
    """ClosedLoop's time per control step [ms] after its first, and every step's (throttle, brake)."""
    loop = ClosedLoop(config)
    loop.step()  # creates the renderer: left out, as the environment's reset is
    start = time.perf_counter()
    while not loop.done():
        loop.step()
    elapsed_s = time.perf_counter() - start
    loop.close()
    commands = [(r.throttle, r.brake) for r in loop.records]
    return 1e3 * elapsed_s / (len(commands) - 1), commands


def _env_ms_per_step(config: SimConfig, images: bool, commands: list[tuple[float, float]]) -> tuple[float, float]:
    """The environment's time per step [ms] replaying `commands`, and its reset time [s]."""
    scenario = config.scenario
    env = gymnasium.make(ENV_ID, town=scenario.town, perception=config.perception.kind, images=images,
                         config_overrides={"scenario": {"start_dist_m": scenario.start_dist_m, "start_speed_kmh": scenario.start_speed_kmh}})
    start = time.perf_counter()
    env.reset(seed=scenario.seed)
    reset_s = time.perf_counter() - start
    start = time.perf_counter()
    for throttle, brake in commands:
        _, _, terminated, truncated, _ = env.step((throttle, brake))
        if terminated or truncated:
            break
    elapsed_s = time.perf_counter() - start
    env.close()
    return 1e3 * elapsed_s / len(commands), reset_s


def print_env_rows(base: SimConfig, perceptions: tuple[str, ...], repeats: int) -> None:
    for perception in perceptions:
        config = with_overrides(base, {"scenario": {"town": "town07"}, "policy": {"name": "baseline"},
                                       "perception": {"kind": perception}})
        loop_ms, commands = min(_loop_ms_per_step(config) for _ in range(repeats))
        plain_ms, reset_s = min(_env_ms_per_step(config, False, commands) for _ in range(repeats))
        image_ms, _ = min(_env_ms_per_step(config, True, commands) for _ in range(repeats))
        print(f"  gym env, {perception:8s} town07, no images       {1e3 / plain_ms:6.1f} steps/s   (ClosedLoop "
              f"{1e3 / loop_ms:.1f} steps/s on the same run: {100 * (plain_ms / loop_ms - 1):+.1f}% a step; target < 10%)")
        print(f"  gym env, {perception:8s} town07, front image     {1e3 / image_ms:6.1f} steps/s   "
              f"(rendering the observed image adds {image_ms - plain_ms:.1f} ms a step; reset {reset_s:.2f} s)")
