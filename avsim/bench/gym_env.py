"""`avsim bench` rows for `avsim/StopSign-v0`: steps per second with and without camera images,
and the environment's cost over `ClosedLoop` doing the same work.

The closed loop runs `baseline` from rest; the environment (made with `gymnasium.make`, its
wrappers included) is then driven with the throttle and brake that run recorded, so both
simulate the same trajectory with the same perception, step for step. Only stepping is timed:
the first closed-loop step (which creates the renderer) and the environment's reset (which
does the same) are left out, and the reset is timed on its own. Each figure is the fastest of
`repeats` runs, since other work on the machine only ever slows a run down. The overhead is also
given in CPU time (this process's, renderer threads included), which other work on a shared
machine disturbs less than wall time.
"""

from __future__ import annotations

import time

import gymnasium

from avsim.config import SimConfig, with_overrides
from avsim.gym import ENV_ID
from avsim.loop import ClosedLoop
from avsim.perception.cpu_bf16 import detector_arithmetic


def _loop_ms_per_step(config: SimConfig) -> tuple[float, float, list[tuple[float, float]]]:
    """ClosedLoop's wall and CPU time per control step after its first [ms], and every step's (throttle, brake)."""
    loop = ClosedLoop(config)
    loop.step()  # creates the renderer: left out, as the environment's reset is
    start, start_cpu = time.perf_counter(), time.process_time()
    while not loop.done():
        loop.step()
    elapsed_s, cpu_s = time.perf_counter() - start, time.process_time() - start_cpu
    loop.close()
    commands = [(r.throttle, r.brake) for r in loop.records]
    steps = len(commands) - 1
    return 1e3 * elapsed_s / steps, 1e3 * cpu_s / steps, commands


def _env_ms_per_step(config: SimConfig, images: bool, commands: list[tuple[float, float]]) -> tuple[float, float, float]:
    """The environment's wall and CPU time per step [ms] replaying `commands`, and its reset time [s]."""
    scenario = config.scenario
    env = gymnasium.make(ENV_ID, town=scenario.town, perception=config.perception.kind, images=images,
                         config_overrides={"scenario": {"start_dist_m": scenario.start_dist_m, "start_speed_kmh": scenario.start_speed_kmh}})
    start = time.perf_counter()
    env.reset(seed=scenario.seed)
    reset_s = time.perf_counter() - start
    start, start_cpu = time.perf_counter(), time.process_time()
    for throttle, brake in commands:
        _, _, terminated, truncated, _ = env.step((throttle, brake))
        if terminated or truncated:
            break
    elapsed_s, cpu_s = time.perf_counter() - start, time.process_time() - start_cpu
    env.close()
    return 1e3 * elapsed_s / len(commands), 1e3 * cpu_s / len(commands), reset_s


def print_env_rows(base: SimConfig, perceptions: tuple[str, ...], repeats: int) -> None:
    """Print one row per perception: the environment's steps per second without and with images,
    and its cost over `ClosedLoop` on the same run (best of `repeats`).
    """
    for perception in perceptions:
        config = with_overrides(base, {"scenario": {"town": "town07"}, "policy": {"name": "baseline"},
                                       "perception": {"kind": perception}})
        loops = [_loop_ms_per_step(config) for _ in range(repeats)]
        commands = loops[0][2]
        plain = [_env_ms_per_step(config, False, commands) for _ in range(repeats)]
        image = [_env_ms_per_step(config, True, commands) for _ in range(repeats)]
        loop_ms, loop_cpu_ms = min(r[0] for r in loops), min(r[1] for r in loops)
        plain_ms, plain_cpu_ms, reset_s = (min(r[i] for r in plain) for i in range(3))
        image_ms = min(r[0] for r in image)
        print(f"  gym env, {perception:8s} town07, no images       {1e3 / plain_ms:6.1f} steps/s   (ClosedLoop "
              f"{1e3 / loop_ms:.1f} steps/s on the same run: {100 * (plain_ms / loop_ms - 1):+.1f}% a step, "
              f"{100 * (plain_cpu_ms / loop_cpu_ms - 1):+.1f}% in CPU time; target < 10%)")
        print(f"  gym env, {perception:8s} town07, front image     {1e3 / image_ms:6.1f} steps/s   "
              f"(rendering the observed image adds {image_ms - plain_ms:.1f} ms a step; reset {reset_s:.2f} s)")


def _vector_steps_per_s(num_envs: int, steps: int) -> tuple[float, float]:
    """(environment steps per wall second, per CPU second) of `gymnasium.make_vec`'s vector entry point
    with `num_envs` detector environments (the default precision, no images), driven with constant cruise actions."""
    import numpy as np

    envs = gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point", perception="detector",
                              images=False)
    envs.reset(seed=0)
    actions = np.tile(np.array([0.3, 0.0], np.float32), (num_envs, 1))
    envs.step(actions)  # first frames of each renderer: left out
    start, start_cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        envs.step(actions)
    elapsed_s, cpu_s = time.perf_counter() - start, time.process_time() - start_cpu
    envs.close()
    return num_envs * steps / elapsed_s, num_envs * steps / cpu_s


def print_vector_rows(counts: tuple[int, ...] = (1, 8, 32), steps: int = 20) -> None:
    """Steps per second of the vector environment at each of `counts` environments."""
    rates = {count: _vector_steps_per_s(count, steps) for count in counts}
    arithmetic = detector_arithmetic("auto")  # what the default ran as: bf16 where the CPU has it
    for count, (per_s, per_cpu_s) in rates.items():
        gain = per_cpu_s / rates[counts[0]][1]
        print(f"  gym make_vec, detector {arithmetic} N={count:<3d}     {per_s:6.1f} env steps/s   ({per_cpu_s:.1f} per CPU second; "
              f"{gain:.2f}x N={counts[0]}'s per CPU second)")
