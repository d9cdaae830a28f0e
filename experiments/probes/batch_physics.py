"""One-off probe: what stepping many cars' physics together could save, measured before building it.

Issue 25 asks for the physics of a lock-step batch through MuJoCo 4's `mujoco.batch.Batch` or N
`MjData`, "whichever measures faster", with the tyre and anti-lock model vectorised over the cars.
avsim steps N `MjData` (one per car, each with its own `MjModel`), and per physics step runs the tyre,
anti-lock and traction model in numpy on the car's four wheels (`Vehicle.advance`). This probe times,
for N cars of one town at 85 km/h, one control tick's physics (25 physics steps a car):

- `as built`: each car's `Vehicle.advance`, tyre model and `mj_step` together;
- `mj_step alone`: the same cars' `mj_step` calls with nothing between them, the C floor of N `MjData`;
- `Batch.step`: the same states copied into a persistent `mujoco.batch.Batch` over the cars' own models
  (`set_models`) on one thread, advanced by one call of 25 substeps, with nothing between them either;
  its positions are checked against the `mj_step` loop's, bit for bit.

The difference between the first and the second is the per-step Python of the tyre model, which is the
most a vectorised tyre model could save (it would still run once a physics step, over all cars); the
third says whether `Batch` itself steps faster than N `mj_step` calls. Each phase runs cruising (drive
torque, traction control watching) and braking (full brake request, anti-lock active). CPU time of this
process, medians over ticks:

    MUJOCO_GL=egl python experiments/probes/batch_physics.py --cars 8 --ticks 40

It is not part of avsim; it writes nothing.
"""

from __future__ import annotations

import argparse
import statistics
import time

import mujoco
import mujoco.batch
import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.vehicle.physics import Controls


def _loops(town: str, cars: int) -> list[ClosedLoop]:
    """`cars` runs of one town at 85 km/h, 150 m out, seeds 0.. (their own models: start jitter differs)."""
    return [ClosedLoop(with_overrides(SimConfig(), {
        "scenario": {"town": town, "seed": seed, "start_speed_kmh": 85, "start_dist_m": 150},
        "perception": {"kind": "oracle"}})) for seed in range(cars)]


def _cpu_ms(fn) -> float:
    start = time.process_time()
    fn()
    return (time.process_time() - start) * 1e3


def _tick_as_built(loops: list[ClosedLoop], controls: Controls) -> None:
    for loop in loops:
        loop.vehicle.apply(controls)
        loop.vehicle.advance(loop.config.loop.substeps)


def _tick_mj_step_alone(loops: list[ClosedLoop]) -> None:
    for loop in loops:
        for _ in range(loop.config.loop.substeps):
            mujoco.mj_step(loop.model, loop.data)


def _batch_of(loops: list[ClosedLoop]) -> mujoco.batch.Batch:
    batch = mujoco.batch.Batch(loops[0].model, len(loops), nthread=1, persistent=True)
    batch.set_models([loop.model for loop in loops])
    return batch


def _load_states(batch: mujoco.batch.Batch, loops: list[ClosedLoop]) -> None:
    """Each car's integration state into its row of the batch (a Batch simulation is that row)."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    for row, loop in enumerate(loops):
        mujoco.mj_getState(loop.model, loop.data, batch.state[row], spec)


def measure(town: str, cars: int, ticks: int) -> None:
    loops = _loops(town, cars)
    substeps = loops[0].config.loop.substeps
    for phase, controls in (("cruising", Controls(throttle=0.3)), ("braking", Controls(brake=1.0))):
        built, alone, batched = [], [], []
        for _ in range(ticks):
            saved = [mujoco.MjData(loop.model) for loop in loops]
            for copy, loop in zip(saved, loops):
                mujoco.mj_copyData(copy, loop.model, loop.data)
            alone.append(_cpu_ms(lambda: _tick_mj_step_alone(loops)))
            stepped = [loop.data.qpos.copy() for loop in loops]
            batch = _batch_of(loops)
            for copy, loop in zip(saved, loops):
                mujoco.mj_copyData(loop.data, loop.model, copy)
            _load_states(batch, loops)
            batched.append(_cpu_ms(lambda: batch.step(nstep=substeps)))
            # Batch promises mj_step's results bit for bit; check it on these states
            assert all(np.array_equal(batch.get_data(row).qpos, q) for row, q in enumerate(stepped))
            # the timed tick as built goes on from the car's real state, tyre model and all
            built.append(_cpu_ms(lambda: _tick_as_built(loops, controls)))
        med = statistics.median
        print(f"{town}, {cars} cars, {phase}: as built {med(built):.2f} ms a tick "
              f"({med(built) / cars:.3f} a car); mj_step alone {med(alone):.2f} ms; Batch.step {med(batched):.2f} ms; "
              f"the tyre model's Python {med(built) - med(alone):.2f} ms ({(med(built) - med(alone)) / cars:.3f} a car)",
              flush=True)
    for loop in loops:
        loop.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--towns", default="town07,town10")
    parser.add_argument("--cars", type=int, default=8)
    parser.add_argument("--ticks", type=int, default=40)
    args = parser.parse_args()
    for town in args.towns.split(","):
        measure(town, args.cars, args.ticks)


if __name__ == "__main__":
    main()
